#pragma once
// Arrays in NumPy's .npz format (a zip of .npy files, stored uncompressed), so users load the
// pixel table with one numpy.load and no lidartwin code. Format: NumPy's NEP 1 (.npy v1.0) inside a
// plain PKZIP archive without zip64, so each array and the whole file stay below 4 GiB.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lidartwin {

class NpzWriter {
 public:
  explicit NpzWriter(const std::filesystem::path& path);  // throws InputError if it cannot create it
  ~NpzWriter();
  NpzWriter(const NpzWriter&) = delete;
  NpzWriter& operator=(const NpzWriter&) = delete;

  // One 1-D array named `name` (numpy.load(...)[name]). Little-endian floats and unsigned ints.
  void add(std::string_view name, std::span<const float> values);
  void add(std::string_view name, std::span<const double> values);
  void add(std::string_view name, std::span<const uint8_t> values);
  void add(std::string_view name, std::span<const uint16_t> values);
  void add(std::string_view name, std::span<const uint32_t> values);
  // Writes the zip directory; the destructor does it too, but cannot report a failure.
  void close();

 private:
  void add_bytes(std::string_view name, std::string_view dtype, size_t count, std::span<const uint8_t> bytes);
  struct Entry {
    std::string name;
    uint32_t crc = 0;
    uint32_t size = 0;
    uint32_t offset = 0;
  };
  std::filesystem::path path_;
  std::ofstream out_;
  std::vector<Entry> entries_;
  uint64_t written_ = 0;
  bool closed_ = false;
};

}  // namespace lidartwin
