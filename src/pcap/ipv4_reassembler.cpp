#include "pcap/ipv4_reassembler.h"

#include <algorithm>
#include <cstring>
#include <iterator>

namespace lidartwin::pcap_detail {
namespace {

// The largest IP payload an IPv4 datagram can carry (16-bit total length minus a 20-byte header).
constexpr uint32_t kMaxIpPayload = 65535 - 20;
// Linux gives up on a fragment set after 30 s (net.ipv4.ipfrag_time); a capture does the same.
constexpr uint64_t kExpiryNs = 30'000'000'000ULL;
// Bounds memory on hostile captures that open many sets and never finish them.
constexpr size_t kMaxPendingSets = 1024;

bool overlaps_agree(const std::vector<uint8_t>& a, uint32_t a_offset, std::span<const uint8_t> b, uint32_t b_offset) {
  const uint32_t begin = std::max(a_offset, b_offset);
  const uint32_t end = std::min(a_offset + static_cast<uint32_t>(a.size()), b_offset + static_cast<uint32_t>(b.size()));
  if (begin >= end) return true;
  return std::memcmp(a.data() + (begin - a_offset), b.data() + (begin - b_offset), end - begin) == 0;
}

}  // namespace

std::optional<std::vector<uint8_t>> Ipv4Reassembler::add(const Ipv4Fragment& fragment, uint64_t timestamp_ns) {
  expire(timestamp_ns);
  const Key key{fragment.src, fragment.dst, fragment.id, fragment.protocol};
  auto [it, inserted] = pending_.try_emplace(key);
  if (inserted) {
    it->second.first_timestamp_ns = timestamp_ns;
    if (pending_.size() > kMaxPendingSets) {
      auto oldest = std::min_element(pending_.begin(), pending_.end(), [](const auto& a, const auto& b) {
        return a.second.first_timestamp_ns < b.second.first_timestamp_ns;
      });
      if (oldest != it) drop(oldest);
    }
  }
  Pending& set = it->second;
  if (set.poisoned) return std::nullopt;
  if (!merge(set, fragment)) {
    set.poisoned = true;
    set.pieces.clear();
    return std::nullopt;
  }
  std::optional<std::vector<uint8_t>> whole = assemble(set);
  if (whole) pending_.erase(it);
  return whole;
}

// Records the fragment in its set; false if it contradicts what the set already holds.
bool Ipv4Reassembler::merge(Pending& set, const Ipv4Fragment& fragment) const {
  const uint32_t begin = fragment.offset;
  const uint32_t end = begin + static_cast<uint32_t>(fragment.payload.size());
  if (end > kMaxIpPayload) return false;
  if (!fragment.more_fragments) {
    if (set.end && *set.end != end) return false;
    set.end = end;
  }
  if (set.end && end > *set.end) return false;
  bool already_held = false;
  for (const Piece& piece : set.pieces) {
    const uint32_t piece_end = piece.offset + static_cast<uint32_t>(piece.bytes.size());
    if (set.end && piece_end > *set.end) return false;
    if (!overlaps_agree(piece.bytes, piece.offset, fragment.payload, begin)) return false;
    already_held = already_held || (piece.offset <= begin && piece_end >= end);
  }
  if (already_held) return true;  // a duplicated frame: keep memory bounded by distinct bytes
  auto position =
      std::find_if(set.pieces.begin(), set.pieces.end(), [&](const Piece& piece) { return piece.offset > begin; });
  set.pieces.insert(position, Piece{begin, {fragment.payload.begin(), fragment.payload.end()}});
  return true;
}

// The datagram if pieces cover [0, end) without a gap (overlaps already agree byte for byte).
std::optional<std::vector<uint8_t>> Ipv4Reassembler::assemble(const Pending& set) {
  if (!set.end) return std::nullopt;
  uint32_t covered = 0;
  for (const Piece& piece : set.pieces) {
    if (piece.offset > covered) return std::nullopt;
    covered = std::max(covered, piece.offset + static_cast<uint32_t>(piece.bytes.size()));
  }
  if (covered < *set.end) return std::nullopt;
  std::vector<uint8_t> whole(*set.end);
  for (const Piece& piece : set.pieces) {
    std::copy(piece.bytes.begin(), piece.bytes.end(), whole.begin() + piece.offset);
  }
  return whole;
}

void Ipv4Reassembler::drop(std::map<Key, Pending>::iterator it) {
  ++(it->second.poisoned ? conflicting_ : incomplete_);
  pending_.erase(it);
}

void Ipv4Reassembler::expire(uint64_t now_ns) {
  for (auto it = pending_.begin(); it != pending_.end();) {
    auto next = std::next(it);
    if (now_ns > it->second.first_timestamp_ns + kExpiryNs) drop(it);
    it = next;
  }
}

void Ipv4Reassembler::finish() {
  while (!pending_.empty()) drop(pending_.begin());
}

}  // namespace lidartwin::pcap_detail
