#pragma once
// Runs the `lidartwin` binary as a user would and keeps what it printed.
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace lidartwin::test {

struct CliRun {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

inline CliRun run_cli(const std::string& arguments) {
  CliRun run;
  FILE* pipe = popen((std::string(LIDARTWIN_BINARY) + " " + arguments + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return run;
  std::array<char, 512> buffer{};
  while (fgets(buffer.data(), static_cast<int>(buffer.size()), pipe)) run.output += buffer.data();
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

}  // namespace lidartwin::test
