#pragma once
// What a reinit derives from a config (protocol doc 2.7): the metadata document and the
// StreamConfig snapshot for the streamer.
#include <cstdint>
#include <memory>

#include <nlohmann/json.hpp>

#include "lidartwin/sensor/sensor.h"

namespace lidartwin {

struct Activation {
  nlohmann::json config;         // the active config, flat (GET sensor/config)
  nlohmann::json metadata_json;  // GET sensor/metadata, sensor_info.status as at activation
  std::shared_ptr<const StreamConfig> stream;
};

// sensor_info as the identity and the initialization_id say (status RUNNING).
SensorInfo sensor_info_of(const SensorIdentity& identity, uint32_t init_id);

// `config` must have passed validate_config. Throws InputError (from make_metadata) when it still
// cannot describe a stream.
Activation activate(const SensorIdentity& identity, const nlohmann::json& config, uint32_t init_id,
                    uint64_t generation);

// A random 24-bit initialization_id, never 0 and never `previous`, so clients see every reinit
// (protocol doc 1.10, 2.4 (e) 6).
uint32_t next_init_id(uint32_t previous);

// prod_sn as the packet header carries it. Throws InputError unless it is decimal digits below
// 2^40 (the header field's width).
uint64_t parse_prod_sn(const std::string& prod_sn);

}  // namespace lidartwin
