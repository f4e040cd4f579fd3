// .npz: PKZIP (APPNOTE 4.3.7 local headers, central directory, end record; method 0 = stored)
// holding .npy v1.0 files (magic, header length, a Python dict literal padded to 64 bytes).
#include "lidartwin/analysis/npz_writer.h"

#include <bit>
#include <limits>

#include <fmt/format.h>
#include <lzma.h>

#include "lidartwin/error.h"

namespace lidartwin {
namespace {

static_assert(std::endian::native == std::endian::little, "the .npy dtypes written here are little-endian");

constexpr uint16_t kDosDate1980 = (0 << 9) | (1 << 5) | 1;  // 1980-01-01: captures stay byte-identical

void put16(std::string& s, uint16_t v) {
  s.push_back(static_cast<char>(v & 0xFF));
  s.push_back(static_cast<char>(v >> 8));
}
void put32(std::string& s, uint32_t v) {
  put16(s, static_cast<uint16_t>(v & 0xFFFF));
  put16(s, static_cast<uint16_t>(v >> 16));
}

std::string npy_header(std::string_view dtype, size_t count) {
  std::string dict = fmt::format("{{'descr': '{}', 'fortran_order': False, 'shape': ({},), }}", dtype, count);
  // magic (6) + version (2) + length (2) + dict + '\n' is a multiple of 64 (NEP 1).
  const size_t unpadded = 10 + dict.size() + 1;
  dict.append((64 - unpadded % 64) % 64, ' ');
  dict.push_back('\n');
  std::string header("\x93NUMPY\x01\x00", 8);
  put16(header, static_cast<uint16_t>(dict.size()));
  return header + dict;
}

template <typename T>
std::span<const uint8_t> bytes_of(std::span<const T> values) {
  return {reinterpret_cast<const uint8_t*>(values.data()), values.size_bytes()};
}

}  // namespace

NpzWriter::NpzWriter(const std::filesystem::path& path) : path_(path), out_(path, std::ios::binary) {
  if (!out_) throw InputError(path.string() + ": cannot create the file");
}

NpzWriter::~NpzWriter() {
  try {
    close();
  } catch (...) {  // reported by an explicit close(); a destructor must not throw
  }
}

void NpzWriter::add(std::string_view name, std::span<const float> v) { add_bytes(name, "<f4", v.size(), bytes_of(v)); }
void NpzWriter::add(std::string_view name, std::span<const double> v) { add_bytes(name, "<f8", v.size(), bytes_of(v)); }
void NpzWriter::add(std::string_view name, std::span<const uint8_t> v) { add_bytes(name, "|u1", v.size(), v); }
void NpzWriter::add(std::string_view name, std::span<const uint16_t> v) {
  add_bytes(name, "<u2", v.size(), bytes_of(v));
}
void NpzWriter::add(std::string_view name, std::span<const uint32_t> v) {
  add_bytes(name, "<u4", v.size(), bytes_of(v));
}

void NpzWriter::add_bytes(std::string_view name, std::string_view dtype, size_t count, std::span<const uint8_t> bytes) {
  const std::string file = std::string(name) + ".npy";
  const std::string header = npy_header(dtype, count);
  const uint64_t size = header.size() + bytes.size();
  constexpr uint64_t kLimit = std::numeric_limits<uint32_t>::max();
  if (size > kLimit || written_ + size + 30 + file.size() > kLimit) {
    throw InputError(fmt::format("{}: array '{}' would take the file past 4 GiB (no zip64 here); compare fewer frames",
                                 path_.string(), name));
  }
  uint32_t crc = lzma_crc32(reinterpret_cast<const uint8_t*>(header.data()), header.size(), 0);
  crc = lzma_crc32(bytes.data(), bytes.size(), crc);
  Entry entry{file, crc, static_cast<uint32_t>(size), static_cast<uint32_t>(written_)};
  std::string local;
  put32(local, 0x04034b50);
  put16(local, 20);  // version needed: 2.0
  put16(local, 0);   // flags
  put16(local, 0);   // stored
  put16(local, 0);   // time
  put16(local, kDosDate1980);
  put32(local, crc);
  put32(local, entry.size);
  put32(local, entry.size);
  put16(local, static_cast<uint16_t>(file.size()));
  put16(local, 0);  // extra
  local += file;
  out_.write(local.data(), static_cast<std::streamsize>(local.size()));
  out_.write(header.data(), static_cast<std::streamsize>(header.size()));
  out_.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out_) throw InputError(path_.string() + ": write failed (disk full?)");
  written_ += local.size() + size;
  entries_.push_back(std::move(entry));
}

void NpzWriter::close() {
  if (closed_) return;
  closed_ = true;
  std::string directory;
  for (const Entry& e : entries_) {
    put32(directory, 0x02014b50);
    put16(directory, 20);  // made by
    put16(directory, 20);  // needed
    put16(directory, 0);
    put16(directory, 0);
    put16(directory, 0);
    put16(directory, kDosDate1980);
    put32(directory, e.crc);
    put32(directory, e.size);
    put32(directory, e.size);
    put16(directory, static_cast<uint16_t>(e.name.size()));
    put16(directory, 0);  // extra
    put16(directory, 0);  // comment
    put16(directory, 0);  // disk
    put16(directory, 0);  // internal attributes
    put32(directory, 0);  // external attributes
    put32(directory, e.offset);
    directory += e.name;
  }
  std::string end;
  put32(end, 0x06054b50);
  put16(end, 0);
  put16(end, 0);
  put16(end, static_cast<uint16_t>(entries_.size()));
  put16(end, static_cast<uint16_t>(entries_.size()));
  put32(end, static_cast<uint32_t>(directory.size()));
  put32(end, static_cast<uint32_t>(written_));
  put16(end, 0);
  out_.write(directory.data(), static_cast<std::streamsize>(directory.size()));
  out_.write(end.data(), static_cast<std::streamsize>(end.size()));
  out_.close();
  if (!out_) throw InputError(path_.string() + ": write failed (disk full?)");
}

}  // namespace lidartwin
