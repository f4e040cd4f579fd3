#pragma once
// Each subcommand lives in its own file and registers itself here, so adding one edits no list.
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

namespace lidartwin::cli {

// Adds a subcommand to the app; the returned callback runs it and gives the exit code.
using CommandSetup = std::function<void(CLI::App& app, std::function<int()>& run)>;

struct Command {
  std::string name;
  CommandSetup setup;
};

std::vector<Command>& commands();

struct RegisterCommand {
  RegisterCommand(std::string name, CommandSetup setup) { commands().push_back({std::move(name), std::move(setup)}); }
};

}  // namespace lidartwin::cli
