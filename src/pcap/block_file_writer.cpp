#include "lidartwin/pcap/block_file_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "lidartwin/error.h"

namespace lidartwin {
namespace {

constexpr int kBlocks = 3;  // one filling, two being written: the disk keeps up with a frame ahead
constexpr int kFlags = O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC;

bool clear_direct(int fd) {
  const int flags = ::fcntl(fd, F_GETFL);
  return flags >= 0 && ::fcntl(fd, F_SETFL, flags & ~O_DIRECT) == 0;
}

}  // namespace

void BlockFileWriter::FreeAligned::operator()(uint8_t* p) const { std::free(p); }

BlockFileWriter::BlockFileWriter(const std::filesystem::path& path, std::string_view contents)
    : name_(path.string()), contents_(contents) {
  // File systems without O_DIRECT (tmpfs before Linux 6.6, some FUSE) refuse it at open(2) with
  // EINVAL; those get buffered writes, still from the writer thread.
  fd_ = ::open(path.c_str(), kFlags | O_DIRECT, 0644);
  direct_ = fd_ >= 0;
  if (fd_ < 0 && errno == EINVAL) fd_ = ::open(path.c_str(), kFlags, 0644);
  if (fd_ < 0) throw InputError(name_ + ": cannot write " + contents_ + ": " + std::strerror(errno));
  for (int i = 0; i < kBlocks; ++i) {
    auto* bytes = static_cast<uint8_t*>(std::aligned_alloc(kAlignment, kBlockBytes));
    if (bytes == nullptr) throw std::bad_alloc();
    storage_.emplace_back(bytes);
    free_.push_back({bytes, 0, 0});
  }
  current_ = free_.back();
  free_.pop_back();
  thread_ = std::thread([this] { write_blocks(); });
}

BlockFileWriter::~BlockFileWriter() {
  try {
    close();
  } catch (const InputError&) {  // reported only to a caller of close()
  }
}

void BlockFileWriter::append(std::span<const uint8_t> bytes) {
  while (!bytes.empty()) {
    const size_t n = std::min(bytes.size(), kBlockBytes - current_.size);
    std::memcpy(current_.bytes + current_.size, bytes.data(), n);
    current_.size += n;
    bytes = bytes.subspan(n);
    if (current_.size == kBlockBytes) submit(false);
  }
}

void BlockFileWriter::close() {
  if (closed_) return;
  closed_ = true;
  submit(true);
  thread_.join();
  const bool closed = ::close(fd_) == 0;
  fd_ = -1;
  if (!closed && !failed_) error_ = name_ + ": cannot write " + contents_ + ": " + std::strerror(errno), failed_ = true;
  throw_if_failed();
}

void BlockFileWriter::submit(bool last) {
  std::unique_lock lock(mutex_);
  current_.offset = next_offset_;
  next_offset_ += current_.size;
  queued_.push_back(current_);
  last_queued_ = last;
  current_ = {};
  changed_.notify_all();
  if (last) return;
  changed_.wait(lock, [this] { return !free_.empty(); });
  current_ = free_.back();
  free_.pop_back();
  current_.size = 0;
  if (failed_) throw InputError(error_);
}

void BlockFileWriter::throw_if_failed() {
  const std::lock_guard lock(mutex_);
  if (failed_) throw InputError(error_);
}

// Blocks in file order; after a failure the rest are returned unwritten, so append() never waits
// for a block that will not come back.
void BlockFileWriter::write_blocks() {
  for (;;) {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [this] { return !queued_.empty(); });
    const Block block = queued_.front();
    queued_.pop_front();
    const bool last = last_queued_ && queued_.empty();
    const bool skip = failed_;
    lock.unlock();
    if (!skip) write_block(block);
    lock.lock();
    free_.push_back(block);
    changed_.notify_all();
    if (last) return;
  }
}

void BlockFileWriter::write_block(const Block& block) {
  const uint8_t* bytes = block.bytes;
  uint64_t offset = block.offset;
  size_t left = block.size;
  while (left > 0) {
    // O_DIRECT takes whole aligned blocks only: a file's unaligned tail (the last block's) is
    // written buffered.
    if (direct_ && left % kAlignment != 0 && left < kAlignment) direct_ = !clear_direct(fd_);
    const size_t n = direct_ ? left / kAlignment * kAlignment : left;
    const ssize_t written = ::pwrite(fd_, bytes, n, static_cast<off_t>(offset));
    if (written < 0 && errno == EINTR) continue;
    // A file system may refuse O_DIRECT only at write time (EINVAL): go on buffered.
    if (written < 0 && errno == EINVAL && direct_ && clear_direct(fd_)) {
      direct_ = false;
      continue;
    }
    if (written <= 0) return fail(written == 0 ? "no progress" : std::strerror(errno));
    bytes += written, offset += static_cast<uint64_t>(written), left -= static_cast<size_t>(written);
  }
}

void BlockFileWriter::fail(const std::string& what) {
  const std::lock_guard lock(mutex_);
  failed_ = true;
  error_ = name_ + ": cannot write " + contents_ + ": " + what;
}

}  // namespace lidartwin
