// An OSF recording read as the analysis reads a capture, judged against the same capture as a pcap
// decoded packet by packet: ouster-sdk's tests ship the lb_n3 OS-1-128 capture both ways.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "lidartwin/analysis/measured_capture.h"
#include "lidartwin/error.h"
#include "lidartwin/pcap/osf.h"

namespace {

using namespace lidartwin;

const std::string kSamples = std::string(LIDARTWIN_TEST_DATA) + "/ouster-samples/";
const std::string kOsf = kSamples + "osfs/OS-1-128_v2.3.0_1024x10_lb_n3.osf";

TEST(OsfCapture, IsToldByItsHeaderNotItsName) {
  EXPECT_TRUE(is_osf_file(kOsf));
  EXPECT_FALSE(is_osf_file(kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap"));
  EXPECT_FALSE(is_osf_file(kSamples + "OS-1-128_v2.3.0_1024x10.json"));
}

TEST(OsfCapture, ReadsItsStreamsAndTheSensorMetadataItCarries) {
  OsfReader reader(kOsf);
  const OsfFileInfo& info = reader.info();
  EXPECT_EQ(info.version_name, "2.1");
  EXPECT_EQ(info.lidar_streams, 1u);
  EXPECT_NE(info.sensor_metadata.find("\"prod_line\""), std::string::npos);
  size_t scans = 0;
  while (auto scan = reader.next()) {
    ++scans;
    EXPECT_EQ(scan->width, 1024);
    EXPECT_EQ(scan->height, 128);
    EXPECT_EQ(scan->images.size(), 3u) << "RNG15_RFL8_NIR8: RANGE, REFLECTIVITY, NEAR_IR";
  }
  EXPECT_EQ(scans, 3u);
}

// The pixels must land where the packets put them: the OSF's PNG fields are destaggered, so a
// reader that forgot to stagger them back (or staggered the wrong way) fails here.
TEST(OsfCapture, HoldsThePixelsThePcapsPacketsCarry) {
  const MeasuredCapture pcap =
      read_capture(kSamples + "OS-1-128_v2.3.0_1024x10_lb_n3.pcap", kSamples + "OS-1-128_v2.3.0_1024x10.json");
  const MeasuredCapture osf = read_capture(kOsf, "");
  EXPECT_EQ(osf.metadata.format, pcap.metadata.format);
  EXPECT_EQ(osf.metadata.sensor_info.prod_sn, pcap.metadata.sensor_info.prod_sn);
  EXPECT_EQ(osf.start_ns, pcap.start_ns);
  ASSERT_EQ(osf.frames.size(), pcap.frames.size());
  for (size_t f = 0; f < osf.frames.size(); ++f) {
    const Scan& a = osf.frames[f].scan;
    const Scan& b = pcap.frames[f].scan;
    EXPECT_EQ(osf.frames[f].frame_id, pcap.frames[f].frame_id);
    EXPECT_EQ(osf.frames[f].complete, pcap.frames[f].complete);
    EXPECT_EQ(a.timestamp_ns, b.timestamp_ns) << "frame " << f;
    EXPECT_EQ(a.status, b.status) << "frame " << f;
    for (const ChannelField c : {ChannelField::kRange, ChannelField::kReflectivity, ChannelField::kNearIr}) {
      ASSERT_TRUE(b.has(c));
      size_t differing = 0, returns = 0;
      for (size_t i = 0; i < b.channels[static_cast<int>(c)].size(); ++i) {
        differing += a.channels[static_cast<int>(c)][i] != b.channels[static_cast<int>(c)][i];
        returns += c == ChannelField::kRange && b.channels[static_cast<int>(c)][i] != 0;
      }
      EXPECT_EQ(differing, 0u) << "frame " << f << ", " << to_string(c);
      if (c == ChannelField::kRange) {
        EXPECT_GT(returns, 50000u) << "a capture with returns to compare";
      }
    }
  }
}

// How much a frame's range jumps from one beam to the next, over pixels where both have a return,
// with each row's columns moved by `shift` (the metadata's pixel shifts: destaggered, the rows of a
// real scene line up, so the jumps are smaller than in the staggered frame).
double row_to_row_jump_mm(const Scan& scan, const std::vector<int>& shift) {
  double sum = 0.0;
  size_t n = 0;
  const int w = scan.width;
  for (int r = 0; r + 1 < scan.height; ++r) {
    for (int c = 0; c < w; ++c) {
      const int a = ((c - shift[static_cast<size_t>(r)]) % w + w) % w;
      const int b = ((c - shift[static_cast<size_t>(r + 1)]) % w + w) % w;
      const double ra = scan.at(ChannelField::kRange, a, r), rb = scan.at(ChannelField::kRange, b, r + 1);
      if (ra == 0 || rb == 0) continue;
      sum += std::min(std::abs(ra - rb), 1000.0);
      ++n;
    }
  }
  return n ? sum / static_cast<double>(n) : 0.0;
}

// ZPNG fields are stored as measured (staggered), PNG ones destaggered: either way the frame must
// come out staggered, as packets carry it. No pcap of single_scan_016 exists, so the scene judges:
// destaggering the frame must line its rows up. Checked first on lb_n3, whose pcap says the truth.
TEST(OsfCapture, FramesComeOutStaggeredFromPngAndZpngFields) {
  for (const std::string name : {"OS-1-128_v2.3.0_1024x10_lb_n3.osf", "single_scan_016.osf"}) {
    const MeasuredCapture osf = read_capture(kSamples + "osfs/" + name, "", 1);
    const std::vector<int>& shift = osf.metadata.format.pixel_shift_by_row;
    const std::vector<int> none(shift.size(), 0);
    const Scan& scan = osf.frames.front().scan;
    const double staggered = row_to_row_jump_mm(scan, none), destaggered = row_to_row_jump_mm(scan, shift);
    EXPECT_LT(destaggered, 0.7 * staggered) << name;
  }
}

// lb_n3 holds every field of its profile (RNG15_RFL8_NIR8); with the metadata of a dual-return
// unit, the second return's fields are missing, and said so.
TEST(OsfCapture, SaysWhichOfTheProfilesFieldsItLacks) {
  EXPECT_TRUE(read_capture(kOsf, "", 1).missing_fields.empty());
  const MeasuredCapture dual =
      read_capture(kOsf, kSamples + "OS-1-128_767798045_1024x10_20230712_120049.json", 1);  // FUSA_RNG15_RFL8_NIR8_DUAL
  EXPECT_EQ(dual.missing_fields, (std::vector<std::string>{"RANGE2", "REFLECTIVITY2"}));
}

TEST(OsfCapture, AMetadataFileGivenBesideItReplacesTheStoredOne) {
  // Another OS-1-128's metadata (1024x10, 128 beams, another serial number and profile).
  const MeasuredCapture stored = read_capture(kOsf, "", 1);
  const MeasuredCapture replaced = read_capture(kOsf, kSamples + "OS-1-128_767798045_1024x10_20230712_120049.json", 1);
  EXPECT_EQ(stored.metadata.sensor_info.prod_sn, "122201000998");
  EXPECT_EQ(replaced.metadata.sensor_info.prod_sn, "122246000293");
  EXPECT_EQ(replaced.frames.size(), 1u);
}

}  // namespace
