// `lidartwin ape` as a user runs it on TUM files: the table on stdout, ape.json and the plot.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace cli_ape_test {

namespace fs = std::filesystem;

namespace {

std::string run(const std::string& arguments, int& code) {
  std::string out;
  FILE* pipe = popen((std::string(LIDARTWIN_BINARY) + " " + arguments + " 2>&1").c_str(), "r");
  char buffer[4096];
  while (size_t n = fread(buffer, 1, sizeof buffer, pipe)) out.append(buffer, n);
  const int status = pclose(pipe);
  code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return out;
}

TEST(CliApe, PrintsEvosStatisticsAndWritesTheJsonAndThePlot) {
  const fs::path dir = fs::path(testing::TempDir()) / ("ape_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  // The estimate is the reference shifted by 3 cm and 4 cm in x and y: 5 cm without alignment,
  // nothing left after SE(3) alignment.
  std::ofstream reference(dir / "gt.tum"), estimate(dir / "est.tum");
  reference.precision(12);
  estimate.precision(12);
  for (int k = 0; k < 50; ++k) {
    const double t = 0.1 * k, x = std::sin(0.5 * t) * 4, y = std::cos(0.3 * t) * 3, z = 0.2 * std::sin(t);
    reference << t << " " << x << " " << y << " " << z << " 0 0 0 1\n";
    estimate << t << " " << x + 0.03 << " " << y + 0.04 << " " << z << " 0 0 0 1\n";
  }
  reference.close();
  estimate.close();
  int code = -1;
  const std::string none = run("ape --reference " + (dir / "gt.tum").string() + " --estimate " +
                                   (dir / "est.tum").string() + " --align none --out " + (dir / "none").string(),
                               code);
  ASSERT_EQ(code, 0) << none;
  EXPECT_NE(none.find("rmse    0.050000"), std::string::npos) << none;
  EXPECT_NE(none.find("50 pose pairs"), std::string::npos) << none;
  const nlohmann::json json = nlohmann::json::parse(std::ifstream(dir / "none" / "ape.json"));
  EXPECT_NEAR(json["rmse_m"].get<double>(), 0.05, 1e-9);
  EXPECT_EQ(json["errors_m"].size(), 50u);
  EXPECT_TRUE(fs::exists(dir / "none" / "ape.png")) << none;

  const std::string aligned =
      run("ape --reference " + (dir / "gt.tum").string() + " --estimate " + (dir / "est.tum").string(), code);
  ASSERT_EQ(code, 0) << aligned;
  EXPECT_NE(aligned.find("rmse    0.000000"), std::string::npos) << aligned;

  const std::string refused = run(
      "ape --reference " + (dir / "gt.tum").string() + " --estimate " + (dir / "est.tum").string() + " --time-offset 5",
      code);
  EXPECT_NE(code, 0);
  EXPECT_NE(refused.find("poses associate within"), std::string::npos) << refused;
  fs::remove_all(dir);
}

}  // namespace

}  // namespace cli_ape_test
