#pragma once
// IPv4 fragment reassembly (RFC 791 / RFC 815), keyed by (source, destination, id, protocol).
// Real Ouster captures hold lidar datagrams split into 1480-byte fragments (protocol doc 9).
#include <array>
#include <compare>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "pcap/frame_decoder.h"

namespace lidartwin::pcap_detail {

class Ipv4Reassembler {
 public:
  // Adds one fragment. Returns the whole IP payload once every byte up to the last fragment's end
  // has arrived. Overlaps with identical bytes (a duplicated frame) are fine; overlaps that
  // disagree, or fragments past the declared end, poison the set, which is then dropped.
  std::optional<std::vector<uint8_t>> add(const Ipv4Fragment& fragment, uint64_t timestamp_ns);
  // Drops every set still pending (end of capture); they count as incomplete or conflicting.
  void finish();

  size_t incomplete() const { return incomplete_; }
  size_t conflicting() const { return conflicting_; }

 private:
  struct Key {
    std::array<uint8_t, 4> src;
    std::array<uint8_t, 4> dst;
    uint16_t id;
    uint8_t protocol;
    auto operator<=>(const Key&) const = default;
  };
  struct Piece {
    uint32_t offset = 0;
    std::vector<uint8_t> bytes;
  };
  struct Pending {
    std::vector<Piece> pieces;  // sorted by offset
    std::optional<uint32_t> end;
    uint64_t first_timestamp_ns = 0;
    bool poisoned = false;
  };

  bool merge(Pending& set, const Ipv4Fragment& fragment) const;
  static std::optional<std::vector<uint8_t>> assemble(const Pending& set);
  void drop(std::map<Key, Pending>::iterator it);
  void expire(uint64_t now_ns);

  std::map<Key, Pending> pending_;
  size_t incomplete_ = 0;
  size_t conflicting_ = 0;
};

}  // namespace lidartwin::pcap_detail
