#pragma once
// Appends bytes to a new file in large aligned blocks written by a background thread, with O_DIRECT
// where the file system takes it: the bytes go from our block to the disk without the page cache.
// A buffered write(2) costs the writing thread a kernel copy and page-cache bookkeeping per 4 KiB
// (on this machine's ext4, 0.25 ns per byte for 32 MB, 1.8 ns once dirty pages are throttled, as a
// long capture's are: 520 MB/s); O_DIRECT took 0.13 ns per byte at 2.9 GB/s, off the render threads.
// `record` writes its capture (~12 bytes per pixel, pcap_writer.cpp) and its column poses (a TUM
// row per column, recorder.cpp) this way.
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace lidartwin {

class BlockFileWriter {
 public:
  static constexpr size_t kBlockBytes = size_t{4} << 20;
  static constexpr size_t kAlignment = 4096;  // O_DIRECT's: a multiple of any logical block size

  // Creates (truncates) the file; throws InputError naming it if it cannot. `contents` names what
  // the file holds in errors: "<file>: cannot write <contents>: <reason>".
  explicit BlockFileWriter(const std::filesystem::path& path, std::string_view contents = "capture");
  ~BlockFileWriter();  // closes, swallowing a write error: call close() to see it
  BlockFileWriter(const BlockFileWriter&) = delete;
  BlockFileWriter& operator=(const BlockFileWriter&) = delete;

  // Copies bytes into the current block; a full block goes to the writer thread. Throws InputError
  // naming the file if an earlier block failed to write (disk full).
  void append(std::span<const uint8_t> bytes);
  // Writes what is left, waits for every block, closes the file. Throws InputError as append does.
  void close();

 private:
  struct Block {
    uint8_t* bytes = nullptr;  // kBlockBytes, aligned to kAlignment
    size_t size = 0;
    uint64_t offset = 0;  // in the file
  };
  struct FreeAligned {
    void operator()(uint8_t* p) const;
  };

  void submit(bool last);
  Block take_free_block();
  void write_blocks();  // the writer thread
  void write_block(const Block& block);
  void fail(const std::string& what);  // on the writer thread
  void throw_if_failed();

  std::string name_;
  std::string contents_;
  int fd_ = -1;
  bool direct_ = false;  // O_DIRECT is set on fd_
  std::vector<std::unique_ptr<uint8_t, FreeAligned>> storage_;
  Block current_;
  uint64_t next_offset_ = 0;
  bool closed_ = false;

  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Block> queued_;  // for the writer thread, in file order
  std::vector<Block> free_;
  bool last_queued_ = false;  // the final (partial) block is queued: the thread ends after it
  bool failed_ = false;
  std::string error_;
  std::thread thread_;
};

}  // namespace lidartwin
