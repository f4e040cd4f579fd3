#pragma once
// An output file that is either absent, the previous run's, or complete: written under a
// temporary name in its directory and renamed over its own name once whole (rename is atomic on
// one file system). A disk that fills, or a process killed halfway, never leaves a truncated
// report or table beside a complete one.
#include <filesystem>
#include <functional>

#include <nlohmann/json.hpp>

namespace lidartwin::cli {

// write(temporary) writes the file; then it takes `path`'s name. When write throws, the temporary
// is removed and the error goes on; a failed rename throws InputError naming `path`.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& temporary)>& write);

// `json` as text (2-space indent, a final newline) at `path`, by write_atomically; throws InputError
// naming `path` when the write fails (a full disk).
void write_json_atomically(const std::filesystem::path& path, const nlohmann::json& json);

}  // namespace lidartwin::cli
