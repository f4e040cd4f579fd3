// `lidartwin pcap-info CAPTURE [--metadata JSON]`: what a capture (pcap or OSF) holds, before anyone
// analyses it.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <memory>
#include <numeric>
#include <string>

#include "cli/command.h"
#include "cli/osf_info.h"
#include "cli/pcap_info.h"

namespace lidartwin::cli {
namespace {

struct PcapInfoFlags {
  std::string capture;
  std::string metadata;
};

void print_datagrams(const std::string& capture, const std::vector<UdpDatagram>& datagrams, const PcapStats& stats) {
  std::cout << "capture: " << capture << "\n"
            << "records: " << stats.records << " (IPv4 fragments: " << stats.fragments << ", not UDP: " << stats.not_udp
            << ", cut by snaplen: " << stats.truncated_frames << ")\n"
            << "udp datagrams: " << datagrams.size()
            << " (incomplete fragment sets dropped: " << stats.incomplete_datagrams
            << ", conflicting: " << stats.conflicting_datagrams << ")\n";
  if (stats.cut_short_record > 0) {
    std::cout << "cut short: the file ends inside record " << stats.cut_short_record << " (a capture interrupted "
              << "while written); the " << stats.records << " records before it were read\n";
  }
  std::cout << "datagrams by destination port and size:\n";
  for (const auto& [port_size, count] : count_datagrams(datagrams)) {
    std::printf("  port %5u  %6zu bytes  x %zu\n", port_size.first, port_size.second, count);
  }
}

void print_metadata(const std::string& path, const Metadata& m) {
  const LidarDataFormat& f = m.format;
  std::cout << "metadata: " << path << "\n"
            << "sensor: " << (m.sensor_info.prod_line.empty() ? "(unnamed)" : m.sensor_info.prod_line) << ", sn "
            << m.sensor_info.prod_sn << ", fw " << m.sensor_info.build_rev << ", init_id "
            << m.sensor_info.initialization_id << "\n"
            << "mode: " << f.columns_per_frame << "x" << f.fps << ", " << f.pixels_per_column << " beams, "
            << f.columns_per_packet << " columns per packet, column window [" << f.column_window[0] << ", "
            << f.column_window[1] << "]\n"
            << "profile: "
            << (m.undecodable_lidar_profile.empty() ? std::string(to_string(f.udp_profile_lidar))
                                                    : m.undecodable_lidar_profile)
            << " (" << to_string(f.header_type) << " header), imu " << to_string(f.udp_profile_imu) << "\n";
}

void print_frames(const LidarSummary& s) {
  std::cout << "frames: " << s.frames.size() << "\n";
  if (s.frames.empty()) return;
  size_t min_columns = SIZE_MAX, max_columns = 0;
  uint64_t pixels = 0, returns = 0, second_returns = 0;
  for (const auto& [id, frame] : s.frames) {
    const auto columns = static_cast<size_t>(std::count(frame.valid_columns.begin(), frame.valid_columns.end(), true));
    min_columns = std::min(min_columns, columns);
    max_columns = std::max(max_columns, columns);
    pixels += frame.pixels;
    returns += frame.returns;
    second_returns += frame.second_returns;
  }
  std::cout << "frame ids: " << s.frames.begin()->first << " .. " << s.frames.rbegin()->first << "\n"
            << "valid columns per frame: " << min_columns;
  if (max_columns != min_columns) std::cout << " .. " << max_columns;
  std::printf("\nvalid pixel fraction: %.4f (range != 0 among %llu pixels of valid columns)\n",
              pixels ? static_cast<double>(returns) / static_cast<double>(pixels) : 0.0,
              static_cast<unsigned long long>(pixels));
  if (s.dual) {
    std::printf("second returns: %.4f of returns (range2 != 0: %llu)\n",
                returns ? static_cast<double>(second_returns) / static_cast<double>(returns) : 0.0,
                static_cast<unsigned long long>(second_returns));
  }
}

void print_lidar(const Metadata& m, const LidarSummary& s) {
  std::cout << "lidar packets: " << s.packets << " (" << s.packet_size << " bytes on port " << s.port
            << (s.port_from_metadata ? "" : ", not the metadata's udp_port_lidar") << ")\n";
  if (s.foreign)
    std::cout << "other sensor or session (prod_sn/init_id differ): " << s.foreign << " packets, skipped\n";
  if (s.malformed) std::cout << "malformed lidar packets: " << s.malformed << " (first: " << s.first_error << ")\n";
  if (s.late)
    std::cout << "late lidar packets (their frame already assembled): " << s.late << ", skipped as the SDK does\n";
  if (m.format.udp_profile_lidar != UdpProfileLidar::kLegacy) {
    std::cout << "crc failures: " << s.crc_failed << " (valid crc: " << s.crc_ok << ", no crc: " << s.without_crc
              << ")\n";
  }
  std::cout << "imu packets: " << s.imu_packets << "\n";
  print_frames(s);
}

void print_osf(const std::string& capture, const OsfSummary& s) {
  const OsfFileInfo& f = s.file;
  std::cout << "capture: " << capture << " (OSF " << f.version_name << ", written by "
            << (f.writer.empty() ? "(unnamed)" : f.writer) << ")\n"
            << "streams and metadata entries:\n";
  for (const OsfEntry& e : f.entries) std::cout << "  " << e.id << "  " << e.type << "\n";
  std::cout << "lidar streams: " << f.lidar_streams << " (reading stream " << f.lidar_stream_id;
  if (f.lidar_streams > 1) std::cout << ", the first; the others are left out";
  std::cout << ")\n";
}

void print_osf_scans(const OsfSummary& s) {
  std::cout << "scans: " << s.scans << "\n";
  if (s.scans == 0) return;
  std::cout << "frame ids: " << s.first_frame_id << " .. " << s.last_frame_id << "\n";
  std::printf("time span: %.6f s (column timestamps %llu .. %llu ns)\n",
              static_cast<double>(s.last_column_ns - s.first_column_ns) * 1e-9,
              static_cast<unsigned long long>(s.first_column_ns), static_cast<unsigned long long>(s.last_column_ns));
  std::cout << "valid columns per scan: " << s.min_valid_columns;
  if (s.max_valid_columns != s.min_valid_columns) std::cout << " .. " << s.max_valid_columns;
  std::printf("\nvalid pixel fraction: %.4f (range != 0 among %llu pixels of valid columns)\n",
              s.pixels ? static_cast<double>(s.returns) / static_cast<double>(s.pixels) : 0.0,
              static_cast<unsigned long long>(s.pixels));
}

// An OSF recording holds scans, not datagrams, and its own metadata (--metadata replaces it).
int run_osf_info(const PcapInfoFlags& flags) {
  const OsfSummary summary = summarize_osf(flags.capture, flags.metadata);
  print_osf(flags.capture, summary);
  print_metadata(flags.metadata.empty() ? "(stored in the OSF file)" : flags.metadata, summary.metadata);
  print_osf_scans(summary);
  return 0;
}

int run_pcap_info(const PcapInfoFlags& flags) {
  if (read_as_osf(flags.capture)) return run_osf_info(flags);
  // Metadata first: a broken metadata file fails before a long capture is read.
  std::unique_ptr<Metadata> metadata;
  if (!flags.metadata.empty()) metadata = std::make_unique<Metadata>(load_metadata(flags.metadata));
  PcapStats stats;
  const std::vector<UdpDatagram> datagrams = read_pcap(flags.capture, stats);
  print_datagrams(flags.capture, datagrams, stats);
  if (!metadata) return 0;
  print_metadata(flags.metadata, *metadata);
  if (!metadata->lidar_enabled()) {
    std::cout << "lidar: off (udp_port_lidar 0 or udp_dest empty in the metadata)\n";
    return 0;
  }
  print_lidar(*metadata, summarize_lidar(datagrams, *metadata));
  return 0;
}

void setup_pcap_info(CLI::App& app, std::function<int()>& run) {
  auto flags = std::make_shared<PcapInfoFlags>();
  CLI::App* sub = app.add_subcommand("pcap-info",
                                     "Summarize a capture: datagrams by port and size; with metadata, "
                                     "lidar packets, frames, valid pixels and CRCs. An OSF recording: its "
                                     "streams, its sensor metadata, scans and time span");
  sub->add_option("capture", flags->capture, "pcap file, or an OSF recording (ouster-cli's .osf)")->required();
  sub->add_option("--metadata", flags->metadata, "sensor metadata JSON (nested or legacy flat)");
  sub->callback([&run, flags] { run = [flags] { return run_pcap_info(*flags); }; });
}

const RegisterCommand registered_pcap_info("pcap-info", setup_pcap_info);

}  // namespace
}  // namespace lidartwin::cli
