// Writing classic (microsecond) pcap files through libpcap's dump API.
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <pcap/pcap.h>

#include "lidartwin/error.h"
#include "lidartwin/pcap/pcap.h"
#include "pcap/frame_encoder.h"

namespace lidartwin {
namespace {

// Large enough for any frame we write (a jumbo frame would still fit); matches tcpdump's default.
constexpr int kSnapLength = 262144;
// stdio's default 4 KiB buffer makes a write(2) every three fragments; `record` writes hundreds of
// MB/s, so the capture goes out in 1 MiB writes.
constexpr size_t kFileBuffer = 1 << 20;

}  // namespace

struct PcapWriter::Impl {
  std::string name;
  pcap_t* dead = nullptr;
  pcap_dumper_t* dumper = nullptr;
  uint16_t next_ip_id = 1;  // a sender's IP id counter: distinct per datagram, as reassembly needs
  pcap_detail::FrameScratch scratch;
  std::vector<char> file_buffer = std::vector<char>(kFileBuffer);  // outlives the FILE it buffers

  ~Impl() {
    if (dumper) pcap_dump_close(dumper);
    if (dead) pcap_close(dead);
  }
};

PcapWriter::PcapWriter(const std::filesystem::path& path) : impl_(std::make_unique<Impl>()) {
  impl_->name = path.string();
  impl_->dead = pcap_open_dead_with_tstamp_precision(DLT_EN10MB, kSnapLength, PCAP_TSTAMP_PRECISION_MICRO);
  if (!impl_->dead) throw InputError(impl_->name + ": cannot create a pcap writer");
  FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) throw InputError(impl_->name + ": cannot write capture: " + std::strerror(errno));
  std::setvbuf(file, impl_->file_buffer.data(), _IOFBF, impl_->file_buffer.size());
  impl_->dumper = pcap_dump_fopen(impl_->dead, file);  // owns the FILE once it succeeds
  if (!impl_->dumper) {
    std::fclose(file);
    throw InputError(impl_->name + ": cannot write capture: " + pcap_geterr(impl_->dead));
  }
}

PcapWriter::~PcapWriter() = default;

void PcapWriter::write(const UdpDatagramView& datagram) {
  Impl& impl = *impl_;
  if (datagram.payload.size() > pcap_detail::kMaxUdpPayload) {
    throw InputError(impl.name + ": UDP payload of " + std::to_string(datagram.payload.size()) +
                     " bytes does not fit one datagram (max " + std::to_string(pcap_detail::kMaxUdpPayload) + ")");
  }
  pcap_pkthdr header{};
  header.ts.tv_sec = static_cast<time_t>(datagram.timestamp_ns / 1'000'000'000ULL);
  header.ts.tv_usec = static_cast<suseconds_t>(datagram.timestamp_ns % 1'000'000'000ULL / 1000);
  pcap_detail::encode_frames(datagram, impl.next_ip_id++, impl.scratch, [&](std::span<const uint8_t> frame) {
    header.caplen = header.len = static_cast<bpf_u_int32>(frame.size());
    pcap_dump(reinterpret_cast<u_char*>(impl.dumper), &header, frame.data());
  });
}

void PcapWriter::flush() {
  if (pcap_dump_flush(impl_->dumper) != 0) throw InputError(impl_->name + ": cannot write capture (disk full?)");
}

}  // namespace lidartwin
