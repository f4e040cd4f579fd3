#include "cli/plot_script.h"

#include <cstdlib>

#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin::cli {

namespace fs = std::filesystem;

std::string run_plot_script(const std::string& script_name, const fs::path& out, const std::string& product) {
  const fs::path script = source_dir() / "tools" / script_name;
  if (!fs::exists(script)) {
    return product + " not written: " + script.string() + " not found (set LIDARTWIN_SOURCE_DIR)";
  }
  // Debian's interpreter first: it is the one tools/setup gives numpy and matplotlib.
  const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  const fs::path log = out / "plots.log";
  const std::string command = python + " '" + script.string() + "' '" + out.string() + "' >'" + log.string() + "' 2>&1";
  if (std::system(command.c_str()) != 0) {
    return product + " not written: " + script_name + " failed (it needs python3 with numpy and matplotlib, which " +
           "tools/setup installs; see " + log.string() + ")";
  }
  fs::remove(log);
  return "wrote " + (out / product).string();
}

}  // namespace lidartwin::cli
