#pragma once
// Why a listening socket could not be bound: httplib reports only failure, so bind once more
// ourselves to learn errno.
#include <string>

namespace lidartwin {

// errno of bind() on address:port (after SO_REUSEADDR, as httplib sets it); 0 if it now works,
// EADDRNOTAVAIL if the address does not resolve.
int bind_errno(const std::string& address, int port);

}  // namespace lidartwin
