#include "cli/atomic_output.h"

#include <fstream>
#include <string>
#include <system_error>

#include <unistd.h>

#include "lidartwin/error.h"

namespace lidartwin::cli {

void write_atomically(const std::filesystem::path& path,
                      const std::function<void(const std::filesystem::path& temporary)>& write) {
  std::filesystem::path temporary = path;
  temporary += ".partial." + std::to_string(::getpid());
  std::error_code ignored;
  try {
    write(temporary);
  } catch (const InputError& e) {
    std::filesystem::remove(temporary, ignored);
    // The user knows the file by its own name, not the temporary's.
    std::string message = e.what();
    for (size_t at = message.find(temporary.string()); at != std::string::npos;
         at = message.find(temporary.string(), at)) {
      message.replace(at, temporary.string().size(), path.string());
    }
    throw InputError(message);
  } catch (...) {
    std::filesystem::remove(temporary, ignored);
    throw;
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    std::filesystem::remove(temporary, ignored);
    throw InputError(path.string() + ": cannot be written: " + error.message());
  }
}

void write_json_atomically(const std::filesystem::path& path, const nlohmann::json& json) {
  write_atomically(path, [&](const std::filesystem::path& file) {
    std::ofstream out(file);
    out << json.dump(2) << "\n";
    out.close();
    if (!out) throw InputError(path.string() + ": write failed (disk full?)");
  });
}

}  // namespace lidartwin::cli
