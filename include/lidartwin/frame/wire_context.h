#pragma once
// What a sensor's data format fixes for every column, written once for the renderer that makes the
// packets and for the analysis that reads them back (scene, static and map tables), so that the
// two cannot drift apart: a context missing the unit's signal gain once made static mode predict
// the wrong SIGNAL.
#include "lidartwin/effects/measurement.h"
#include "lidartwin/packet/lidar_packet.h"

namespace lidartwin {

// The wire's range step and limit (E9), the unit's signal gain (signal_multiplier, E18) and the
// columns per rotation; each column's frame, measurement id and time are its own.
ColumnContext wire_context(const PacketFormat& packets, float signal_gain);

// How far rays are cast: 1 m past the profile's maximum range, so range noise can still carry a
// return across it and the chain's range_limits decide (E16), and never beyond what the wire can
// carry (E9).
float cast_reach_m(double max_range_m, const PacketFormat& packets);

}  // namespace lidartwin
