#pragma once
// An output file that is either absent, the previous run's, or complete: written under a
// temporary name in its directory and renamed over its own name once whole (rename is atomic on
// one file system). A disk that fills, or a process killed halfway, never leaves a truncated
// report or table beside a complete one.
#include <filesystem>
#include <functional>

namespace lidartwin::cli {

// write(temporary) writes the file; then it takes `path`'s name. When write throws, the temporary
// is removed and the error goes on; a failed rename throws InputError naming `path`.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& temporary)>& write);

}  // namespace lidartwin::cli
