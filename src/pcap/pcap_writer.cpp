// Writing classic (microsecond) pcap files: the file and record headers as libpcap's dump API
// writes them (host byte order, which readers detect from the magic), each datagram's frames with
// one writev of their headers and payload slices. libpcap's pcap_dump goes through stdio, which
// copies every frame into its buffer after we had assembled it in ours; here the payload is copied
// once, by the kernel, straight from the caller's buffer (`record` writes ~300 MB/s).
#include <fcntl.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lidartwin/error.h"
#include "lidartwin/pcap/block_file_writer.h"
#include "lidartwin/pcap/pcap.h"
#include "pcap/frame_encoder.h"

namespace lidartwin {
namespace {

constexpr uint32_t kMagicMicroseconds = 0xA1B2C3D4;
constexpr uint32_t kSnapLength = 262144;  // larger than any frame we write; tcpdump's default
constexpr uint32_t kLinkTypeEthernet = 1;

struct FileHeader {
  uint32_t magic = kMagicMicroseconds;
  uint16_t version_major = 2;
  uint16_t version_minor = 4;
  int32_t this_zone = 0;
  uint32_t sigfigs = 0;
  uint32_t snap_length = kSnapLength;
  uint32_t link_type = kLinkTypeEthernet;
};
static_assert(sizeof(FileHeader) == 24);

struct RecordHeader {
  uint32_t seconds = 0;
  uint32_t microseconds = 0;
  uint32_t captured = 0;
  uint32_t length = 0;
};
static_assert(sizeof(RecordHeader) == 16);

std::string system_error() { return std::strerror(errno); }

}  // namespace

struct PcapWriter::Impl {
  std::string name;
  int fd = -1;                                  // kEachDatagram
  std::optional<BlockFileWriter> blocks;        // kInBlocks
  uint16_t next_ip_id = 1;                      // a sender's IP id counter: distinct per datagram, as reassembly needs
  std::vector<pcap_detail::FrameParts> frames;  // reused between datagrams
  std::vector<RecordHeader> records;
  std::vector<iovec> pieces;

  ~Impl() {
    if (fd >= 0) ::close(fd);
  }

  void write_all() {
    if (!blocks) return write_now();
    for (const iovec& piece : pieces) blocks->append({static_cast<const uint8_t*>(piece.iov_base), piece.iov_len});
  }

  // All of pieces, resuming after a short write (a signal, a full pipe).
  void write_now() {
    iovec* piece = pieces.data();
    size_t left = pieces.size();
    while (left > 0) {
      const ssize_t written = ::writev(fd, piece, static_cast<int>(std::min<size_t>(left, IOV_MAX)));
      if (written < 0 && errno == EINTR) continue;
      if (written < 0) throw InputError(name + ": cannot write capture: " + system_error());
      auto done = static_cast<size_t>(written);
      while (left > 0 && done >= piece->iov_len) {
        done -= piece->iov_len;
        ++piece, --left;
      }
      if (left > 0) {
        piece->iov_base = static_cast<uint8_t*>(piece->iov_base) + done;
        piece->iov_len -= done;
      }
    }
  }
};

PcapWriter::PcapWriter(const std::filesystem::path& path, PcapFlush flush) : impl_(std::make_unique<Impl>()) {
  impl_->name = path.string();
  if (flush == PcapFlush::kInBlocks) {
    impl_->blocks.emplace(path);
  } else {
    impl_->fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (impl_->fd < 0) throw InputError(impl_->name + ": cannot write capture: " + system_error());
  }
  FileHeader header;
  impl_->pieces = {{&header, sizeof header}};
  impl_->write_all();
}

PcapWriter::~PcapWriter() = default;

void PcapWriter::close() {
  Impl& impl = *impl_;
  if (impl.blocks) return impl.blocks->close();
  if (impl.fd < 0) return;
  const int fd = std::exchange(impl.fd, -1);
  if (::close(fd) != 0) throw InputError(impl.name + ": cannot write capture: " + system_error());
}

void PcapWriter::write(const UdpDatagramView& datagram) {
  Impl& impl = *impl_;
  if (datagram.payload.size() > pcap_detail::kMaxUdpPayload) {
    throw InputError(impl.name + ": UDP payload of " + std::to_string(datagram.payload.size()) +
                     " bytes does not fit one datagram (max " + std::to_string(pcap_detail::kMaxUdpPayload) + ")");
  }
  pcap_detail::split_frames(datagram, impl.next_ip_id++, impl.frames);
  const auto seconds = static_cast<uint32_t>(datagram.timestamp_ns / 1'000'000'000ULL);
  const auto microseconds = static_cast<uint32_t>(datagram.timestamp_ns % 1'000'000'000ULL / 1000);
  impl.records.resize(impl.frames.size());
  impl.pieces.clear();
  for (size_t i = 0; i < impl.frames.size(); ++i) {
    pcap_detail::FrameParts& frame = impl.frames[i];
    const auto size = static_cast<uint32_t>(frame.size());
    impl.records[i] = {seconds, microseconds, size, size};
    impl.pieces.push_back({&impl.records[i], sizeof(RecordHeader)});
    impl.pieces.push_back({frame.header.data(), frame.header_size});
    if (frame.payload_size > 0) {
      // writev takes non-const bases; it only reads them.
      impl.pieces.push_back({const_cast<uint8_t*>(datagram.payload.data() + frame.payload_offset), frame.payload_size});
    }
  }
  impl.write_all();
}

}  // namespace lidartwin
