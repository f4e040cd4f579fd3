#pragma once
// What `--profile` names in serve, record and fit: a shipped profile (os1-64), a profile file, or
// a real unit's metadata file (what GET /api/v1/sensor/metadata or ouster-cli saved, nested FW 3.x
// or legacy flat FW 2.x). A metadata file makes a twin of that unit: its product, part number and
// beam intrinsics, with the effect chain, ranges, divergence, IMU noise and lidar modes of the
// shipped profile of its product line ("OS-1-128" -> os1-128), which `fit` then refines.
#include <optional>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "lidartwin/effects/effect_chain.h"
#include "lidartwin/metadata/metadata.h"
#include "lidartwin/profile/sensor_profile.h"

namespace lidartwin::cli {

struct SensorChoice {
  SensorProfile profile;
  nlohmann::json document;       // the profile as a profile file holds it: what `fit` extends
  std::optional<Metadata> unit;  // the unit's metadata, when --profile named a metadata file
};

// Throws InputError naming the file and the key: a metadata file without a product line, one whose
// product line has no shipped profile, beams that differ from the product line's, and everything
// parse_metadata and parse_profile refuse.
SensorChoice load_sensor(const std::string& name_or_path);

// The profile's effect chain; its errors name "profile <name>: /effects/<i>/<key>".
EffectChain profile_chain(const SensorProfile& profile);

// Whether a JSON document is sensor metadata rather than a profile: it has metadata keys (one of
// the 7 nested sections, or the flat layout's beam angles, lidar_mode or prod_sn) and no effects.
bool is_sensor_metadata(const nlohmann::json& document);

// The shipped profile of a product line: "OS-1-128" -> "os1-128", "OS-0-32-U1" -> "os0-32";
// empty when the line is not OS-<0|1|2>-<beams>[-variant].
std::string profile_family(const std::string& prod_line);

// The twin's profile document: the family's, with the unit's prod_line, prod_pn and beam
// intrinsics, the unit's lidar mode added to the modes if the family lacks it, and a source
// naming the file. `unit_file` is how the user named it.
nlohmann::json twin_document(const Metadata& unit, const std::string& unit_file, const nlohmann::json& family,
                             const std::string& family_name);

// The config the unit's metadata says it ran: lidar_mode, udp_profile_lidar (when this project can
// encode it) and columns_per_packet. The twin starts in it unless flags or a saved state say
// otherwise.
nlohmann::json unit_start_config(const Metadata& unit);

// Major and minor firmware version in an image_rev, as the SDK reads it to choose its API
// (protocol doc 2.2): "ousteros-image-prod-aries-v2.3.0+2022..." -> {2, 3}; nullopt without one.
std::optional<std::pair<int, int>> firmware_version(const std::string& image_rev);

}  // namespace lidartwin::cli
