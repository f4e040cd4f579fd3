// lidartwin: one binary, subcommands registered by the files beside this one.
#include <algorithm>
#include <exception>
#include <functional>
#include <iostream>

#include <CLI/CLI.hpp>

#include "cli/command.h"
#include "lidartwin/error.h"

namespace lidartwin::cli {
std::vector<Command>& commands() {
  static std::vector<Command> all;
  return all;
}
}  // namespace lidartwin::cli

int main(int argc, char** argv) {
  using namespace lidartwin;
  CLI::App app{"lidartwin: a virtual Ouster lidar (emulator, recorder and model analysis)"};
  app.require_subcommand(0, 1);
  auto& registered = cli::commands();
  std::sort(registered.begin(), registered.end(),
            [](const cli::Command& a, const cli::Command& b) { return a.name < b.name; });
  std::function<int()> run;
  for (auto& command : registered) command.setup(app, run);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (!run) {
    std::cout << app.help();
    return 0;
  }
  try {
    return run();
  } catch (const InputError& e) {
    std::cerr << "lidartwin: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "lidartwin: error: " << e.what() << "\n";
    return 1;
  }
}
