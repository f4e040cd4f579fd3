// The CLI starts and lists its subcommands: the cheapest check that the build links.
#include <array>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

namespace cli_smoke_test {

TEST(Cli, PrintsHelpWithoutArguments) {
  std::string output;
  FILE* pipe = popen(LIDARTWIN_BINARY " 2>&1", "r");
  ASSERT_NE(pipe, nullptr);
  std::array<char, 256> buffer{};
  while (fgets(buffer.data(), buffer.size(), pipe)) output += buffer.data();
  EXPECT_EQ(pclose(pipe), 0);
  EXPECT_NE(output.find("virtual Ouster lidar"), std::string::npos) << output;
}

}  // namespace cli_smoke_test
