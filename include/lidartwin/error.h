#pragma once
// Errors at the boundary: a file, JSON body, CLI argument or packet that is wrong. The message names
// the input and the problem (see STYLE.md "Errors at the boundary"). Broken invariants inside the
// core are bugs and use assert, not this.
#include <stdexcept>
#include <string>

namespace lidartwin {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace lidartwin
