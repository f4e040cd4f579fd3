// pixels.npz is read by NumPy itself (Debian's python3-numpy, which tools/setup installs).
#include "lidartwin/analysis/npz_writer.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace lidartwin {
namespace {

std::string run(const std::string& command) {
  std::string out;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return out;
  char buffer[4096];
  while (size_t n = fread(buffer, 1, sizeof buffer, pipe)) out.append(buffer, n);
  pclose(pipe);
  return out;
}

TEST(NpzWriter, NumpyLoadsEveryArrayWithItsTypeAndValues) {
  const auto path = std::filesystem::path(testing::TempDir()) / "arrays.npz";
  {
    NpzWriter npz(path);
    const std::vector<float> f{1.5f, -2.25f, 3.0f};
    const std::vector<double> d{0.1, 1e300};
    const std::vector<uint8_t> u1{0, 255};
    const std::vector<uint16_t> u2{65535, 7, 8};
    const std::vector<uint32_t> u4{4000000000u};
    npz.add("f", std::span<const float>(f));
    npz.add("d", std::span<const double>(d));
    npz.add("u1", std::span<const uint8_t>(u1));
    npz.add("u2", std::span<const uint16_t>(u2));
    npz.add("u4", std::span<const uint32_t>(u4));
    npz.add("empty", std::span<const float>());
    npz.close();
  }
  const std::string script =
      "import numpy as np, zipfile; zipfile.ZipFile('" + path.string() + "').testzip(); d = np.load('" + path.string() +
      "'); print(sorted(d.files)); print(';'.join(f'{k}:{d[k].dtype}:{d[k].tolist()}' for k in sorted(d.files)))";
  const std::string out = run("/usr/bin/python3 -c \"" + script + "\" 2>&1");
  EXPECT_EQ(out,
            "['d', 'empty', 'f', 'u1', 'u2', 'u4']\n"
            "d:float64:[0.1, 1e+300];empty:float32:[];f:float32:[1.5, -2.25, 3.0];u1:uint8:[0, 255];"
            "u2:uint16:[65535, 7, 8];u4:uint32:[4000000000]\n");
}

TEST(NpzWriter, AnUnwritablePathIsAnInputErrorNamingIt) {
  try {
    NpzWriter npz("/nonexistent-dir/pixels.npz");
    FAIL() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/pixels.npz"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lidartwin
