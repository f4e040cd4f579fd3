// Reinit: config -> metadata (make_metadata) -> StreamConfig (protocol doc 2.7).
#include "sensor/activation.h"

#include <algorithm>
#include <cctype>
#include <random>

#include "lidartwin/error.h"
#include "sensor/ipv4.h"

namespace lidartwin {

SensorInfo sensor_info_of(const SensorIdentity& identity, uint32_t init_id) {
  SensorInfo info;
  info.prod_line = identity.prod_line;
  info.prod_pn = identity.prod_pn;
  info.prod_sn = identity.prod_sn;
  info.image_rev = identity.image_rev;
  info.build_rev = identity.build_rev;
  info.build_date = identity.build_date;
  info.initialization_id = init_id;
  return info;
}

Activation activate(const SensorIdentity& identity, const nlohmann::json& config, uint32_t init_id,
                    uint64_t generation) {
  auto stream = std::make_shared<StreamConfig>();
  stream->generation = generation;
  stream->metadata = make_metadata(sensor_info_of(identity, init_id), identity.beams, config);
  // Validated beforehand: udp_dest is an IPv4 literal, the ports are in range.
  stream->udp_dest = parse_ipv4(config.at("udp_dest").get<std::string>()).value();
  stream->udp_port_lidar = config.at("udp_port_lidar").get<uint16_t>();
  stream->udp_port_imu = config.at("udp_port_imu").get<uint16_t>();
  stream->streaming = config.value("operating_mode", "NORMAL") == "NORMAL";
  stream->timestamp_mode = config.value("timestamp_mode", "TIME_FROM_INTERNAL_OSC");
  stream->signal_multiplier = config.value("signal_multiplier", 1.0f);
  stream->init_id = init_id;
  stream->prod_sn = parse_prod_sn(identity.prod_sn);

  Activation activation;
  activation.config = config;
  activation.metadata_json = to_nested_json(stream->metadata);
  activation.stream = std::move(stream);
  return activation;
}

uint32_t next_init_id(uint32_t previous) {
  // Not simulation randomness (nothing to reproduce): a fresh id per reinit, as the FW picks one.
  std::random_device device;
  for (;;) {
    const uint32_t id = device() & 0xFFFFFFu;
    if (id != 0 && id != previous) return id;
  }
}

uint64_t parse_prod_sn(const std::string& prod_sn) {
  const bool digits = !prod_sn.empty() && prod_sn.size() <= 13 &&
                      std::all_of(prod_sn.begin(), prod_sn.end(),
                                  [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; });
  const uint64_t value = digits ? std::stoull(prod_sn) : 0;
  if (!digits || value >= (uint64_t{1} << 40)) {
    throw InputError("prod_sn \"" + prod_sn + "\": must be decimal digits below 2^40 (the packet header has 40 bits)");
  }
  return value;
}

}  // namespace lidartwin
