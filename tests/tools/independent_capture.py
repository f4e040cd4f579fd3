#!/usr/bin/python3
"""Independent test-data generator for lidartwin: a synthetic Ouster OS-1-64 capture of a closed room.

This file is written ONLY from the Ouster protocol reference (ouster-protocol.md) and from the
test plan, without looking at lidartwin's own sources, so that a mistake shared by lidartwin's
packet writer and reader cannot hide. Sections of the doc it relies on:
  3.1 / 3.5  nested FW 3.x metadata (all 7 required sections + imu_data_format)
  3.4        pixel_shift_by_row = round(beam_azimuth_angle * W / 360)
  4.1        packet sizes (32 B header, 12 B column header, 12 B/pixel, 32 B footer -> 12544 B)
  4.3-4.6    STANDARD packet header, column header, footer with CRC-64/XZ, RNG19_RFL8_SIG16_NIR16 pixels
  6.1 / 6.2  1024x10 timing, frame_id / measurement_id / init_id rules
  7.1 / 7.2  the SDK's XYZ projection and its exact inverse (range = distance along the ray), each
             column cast from the sensor's pose at that column's own time
  9          classic libpcap captures with one Ethernet/IPv4/UDP record per lidar packet

Files written to OUT_DIR:
  scene.gltf     glTF 2.0 box room (buffer embedded as a base64 data URI). World (Z up) box
                 x[-10,12] y[-7,6] z[-1.5,4.5] m; world = M * gltf with M = [[1,0,0],[0,0,-1],[0,1,0]].
                 By default one mesh and one material, extras {"reflectivity": 0.5}; with
                 --wall-reflectivity one node, mesh and material per wall (named wall_x_min, wall_x_max,
                 wall_y_min, wall_y_max, wall_z_min = the floor, wall_z_max = the ceiling, in that
                 order), each material's extras {"reflectivity": R} with its wall's R.
  pose.tum       the ground-truth trajectory world_from_sensor (the Ouster sensor frame of 7.2 in the
                 world frame above), TUM "t tx ty tz qx qy qz qw" (metres, unit quaternion).
                 Static sensor: one line "0 X Y Z 0 0 0 1" (at the origin "0 0 0 0 0 0 0 1"), a fixed
                 pose. Moving sensor: frames + 1 knots stamped on the capture's column-timestamp clock
                 in seconds (column timestamp ns / 1e9; the first column is at 1.0 s): one at each
                 frame's first column, t = 1.0 + 0.1 k, and one where the last frame ends. Between two
                 knots the motion is linear in t and its rotation one turn about world Z at a constant
                 rate (less than 180 deg per frame), so linear interpolation of the translation and
                 SLERP of the rotation reproduce the pose of every column exactly.
  metadata.json  OS-1-64, 1024x10, RNG19_RFL8_SIG16_NIR16, 16 columns per packet.
  capture.pcap   --frames frames x 64 lidar packets of 12544 B, 192.168.1.10:7502 -> 192.168.1.100:7502,
                 unfragmented (jumbo) IPv4.
  truth.json     the hidden effects' and the radiometry's true values; with --wall-reflectivity the
                 walls' ("wall_reflectivity"), with motion or --start the motion's ("motion").

Motion (--velocity VX VY VZ m/s in the world frame, --yaw-rate DEG_PER_S about world Z, --start X Y Z;
all 0 by default: a static sensor whose frame is the world frame, as before these options existed).
Column c (measurement id) of frame f has timestamp t_c = 1 s + f * 0.1 s + floor(c * 1e8 / 1024) ns
(6.1), the same value its column header carries, and is cast from the pose at t_c:
  p(t) = start + velocity * (t - t0),  R(t) = Rz(yaw_rate * (t - t0)),  t0 = the first column's time,
so at t0 the sensor's axes are the world's, at position --start. A ray (O_s, D_s) of 7.1 goes to the
world as (R(t_c) O_s + p(t_c), R(t_c) D_s). All 64 rows of a column share its time and pose. The
generator refuses (exit status 1, a message saying when and where) a motion that brings the sensor
within 0.5 m of a wall between the first column and the end of the last frame.

Range model: for beam (row r, measurement id m) the ray of section 7.1 (origin O_s, unit direction D_s in
the sensor frame, mm), taken to the world by the column's pose, is intersected analytically with the
box; the distance s along D_s is the noise-free range. Gaussian noise with sigma = sigma0 + slope * s[m]
(metres) is added, then the value is rounded to whole mm.

Radiometry (lidar-physics.md 2.2, with this generator's own constants, written to truth.json):
  S = K rho cos(theta) g(r) / r^2, g(r) = 1 / (1 + (r0 / r)^p)   expected signal photons
  B = A rho                                                     expected ambient (near-IR) photons
  SIGNAL ~ Poisson(S), NEAR_IR ~ Poisson(B), REFLECTIVITY = round(100 rho cos(theta))
with K = 2.2e5 photons m^2, r0 = 5 m, p = 3, A = 30 photons and rho the diffuse reflectivity of the
wall the ray meets (0.5 everywhere unless --wall-reflectivity), theta the incidence on that wall.

Hidden effects, written from lidar-physics.md's models alone (all off by default):
  E4  --divergence G          variance += (r tan(theta) G / 2.355)^2, theta the incidence on the wall
  E10 --beam-offset-sigma S   r' = (1 + s_b) r + dr_b, dr_b ~ N(0, S), s_b ~ N(0, --beam-scale-sigma),
                              per beam, drawn from --beam-seed (one unit)
      --beam-offset B M       beam B's offset dr_B += M metres (repeatable), as a real unit's one
                              badly calibrated beam
  E12 --drift-mu0 A --drift-muinf B --drift-tau T
                              common-mode offset mu(t) = B + (A - B) exp(-t / T), t the column's time
                              since the capture's first column
  E2  --snr-k K               variance += K^2 (S + B) / S^2 (signal-dependent precision)
  E2  --tail-probability P --tail-half-signal S0 --tail-sigma M
                              tails: with probability P / (1 + S / S0) a return's range gets another
                              N(0, M^2) (3.3's second, wider Gaussian of the outliers)
  E5  --detect-threshold T --detect-width W
                              a return is reported with probability 1 / (1 + exp(-(ln S - ln T) / W));
                              otherwise range, signal and reflectivity are 0
The true values go to truth.json beside the capture (per-beam offsets and scales, radiometry and the
range noise's sigma0 and slope included).

Run (numpy is needed; use the system interpreter):
  /usr/bin/python3 tests/tools/independent_capture.py OUT_DIR [--frames N] [--seed S]
                   [--sigma0 0.01] [--slope 0.0014] [hidden effects]
                   [--velocity VX VY VZ] [--yaw-rate DEG_PER_S] [--start X Y Z]
                   [--wall-reflectivity X_MIN X_MAX Y_MIN Y_MAX Z_MIN Z_MAX]
Use --sigma0 0 --slope 0 for noise-free ranges (each decoded point, taken to the world by its column's
pose, then lies within 0.5 mm of a wall). With the default options the output is byte for byte what
the generator wrote before the motion and wall options existed.
"""

import argparse
import base64
import json
import os
import struct

import numpy as np

# ---------------------------------------------------------------- scene and sensor constants
BOX_MIN_M = np.array([-10.0, -7.0, -1.5])   # world frame, Z up, metres
BOX_MAX_M = np.array([12.0, 6.0, 4.5])
GLTF_TO_WORLD = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float)

W, H, FPS, CPP = 1024, 64, 10, 16           # lidar_mode 1024x10, 64 beams, columns_per_packet
PIXEL_BYTES = 12                             # RNG19_RFL8_SIG16_NIR16 (4.1)
COLUMN_BYTES = 12 + H * PIXEL_BYTES          # column header + pixels (4.1, 4.4)
PACKET_BYTES = 32 + CPP * COLUMN_BYTES + 32  # header + columns + footer = 12544 (4.1 table)
PROD_SN = "992211000123"
INIT_ID = 5431201
BEAM_ORIGIN_MM = 15.806                      # OS-1 lidar_origin_to_beam_origin_mm (3.1)
LIDAR_TO_SENSOR = [-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 36.18, 0, 0, 0, 1]   # 3.5 / 7.3
T0_NS, FRAME_NS = 1_000_000_000, 100_000_000

SRC_IP, DST_IP, LIDAR_PORT, IMU_PORT = "192.168.1.10", "192.168.1.100", 7502, 7503
SRC_MAC = bytes.fromhex("bc0fa7000123")      # made-up sensor MAC
DST_MAC = bytes.fromhex("020000000064")      # made-up host MAC (locally administered)


# ---------------------------------------------------------------- CRC-64/XZ (4.5)
def _crc64_table():
    poly = 0xC96C5795D7870F42                # reflected ECMA-182 polynomial
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ poly if crc & 1 else crc >> 1
        table.append(crc)
    return table


_CRC64_TABLE = _crc64_table()


def crc64_xz(data):
    """CRC-64/XZ: reflected, init all ones, final XOR all ones."""
    crc = 0xFFFFFFFFFFFFFFFF
    table = _CRC64_TABLE
    for b in data:
        crc = table[(crc ^ b) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFFFFFFFFFF


assert crc64_xz(b"123456789") == 0x995DC9BBDF1939FA, "CRC-64/XZ self-check failed"


# ---------------------------------------------------------------- metadata (3.1, 3.4, 3.5)
def beam_angles():
    """Plausible OS-1-64 intrinsics: altitudes +16.6..-16.6 deg (row 0 highest, 7.2), azimuths in the
    repeating +4.2/+1.4/-1.4/-4.2 deg pattern with a small deterministic per-row variation."""
    rows = np.arange(H)
    alt = np.linspace(16.6, -16.6, H) + 0.012 * np.sin(rows * 0.7)
    az = np.array([4.2, 1.4, -1.4, -4.2])[rows % 4] + 0.03 * np.cos(rows * 0.37)
    return np.round(alt, 3), np.round(az, 3)


def beam_to_lidar_transform():
    """Identity with [0][3] = lidar_origin_to_beam_origin_mm (3.1 default, 7.2 consistency rule)."""
    return [1, 0, 0, BEAM_ORIGIN_MM, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def make_metadata():
    alt, az = beam_angles()
    shift = [int(round(a * W / 360.0)) for a in az]          # 3.4, FW 3.x convention
    profile = "RNG19_RFL8_SIG16_NIR16"
    return {
        "sensor_info": {
            "build_date": "2024-04-26T02:34:31Z", "build_rev": "v3.1.0",
            "image_rev": "ousteros-image-prod-bootes-v3.1.0+20240426041747",
            "initialization_id": INIT_ID, "prod_line": "OS-1-64", "prod_pn": "840-102145-D",
            "prod_sn": PROD_SN, "status": "RUNNING"},
        "beam_intrinsics": {
            "beam_altitude_angles": [float(a) for a in alt],
            "beam_azimuth_angles": [float(a) for a in az],
            "beam_to_lidar_transform": beam_to_lidar_transform(),
            "lidar_origin_to_beam_origin_mm": BEAM_ORIGIN_MM},
        "imu_intrinsics": {"imu_to_sensor_transform":
                           [1, 0, 0, 6.253, 0, 1, 0, -11.775, 0, 0, 1, 7.645, 0, 0, 0, 1]},
        "lidar_intrinsics": {"lidar_to_sensor_transform": LIDAR_TO_SENSOR},
        "lidar_data_format": {
            "column_window": [0, W - 1], "columns_per_frame": W, "columns_per_packet": CPP,
            "fps": FPS, "pixel_shift_by_row": shift, "pixels_per_column": H,
            "udp_profile_imu": "LEGACY", "udp_profile_lidar": profile},
        "imu_data_format": {"accel_fsr": "NORMAL", "gyro_fsr": "NORMAL"},
        "calibration_status": {"reflectivity": {"timestamp": "2024-01-01T00:00:00", "valid": True}},
        "config_params": {
            "azimuth_window": [0, 360000], "columns_per_packet": CPP, "lidar_mode": f"{W}x{FPS}",
            "multipurpose_io_mode": "OFF", "operating_mode": "NORMAL", "signal_multiplier": 1,
            "timestamp_mode": "TIME_FROM_INTERNAL_OSC", "udp_dest": DST_IP,
            "udp_port_imu": IMU_PORT, "udp_port_lidar": LIDAR_PORT, "udp_profile_imu": "LEGACY",
            "udp_profile_lidar": profile},
    }


# ---------------------------------------------------------------- scene.gltf and pose.tum
def box_triangles_gltf():
    """8 corners of the box in glTF coordinates (gltf = M^T * world) and 12 inward-facing triangles."""
    lo_g = GLTF_TO_WORLD.T @ BOX_MIN_M
    hi_g = GLTF_TO_WORLD.T @ BOX_MAX_M
    lo, hi = np.minimum(lo_g, hi_g), np.maximum(lo_g, hi_g)
    corners = np.array([[(hi if (i >> k) & 1 else lo)[k] for k in range(3)] for i in range(8)])
    centre = (lo + hi) / 2
    faces = [(0, 2, 6, 4), (1, 3, 7, 5), (0, 1, 5, 4), (2, 3, 7, 6), (0, 1, 3, 2), (4, 5, 7, 6)]
    tris = []
    for a, b, c, d in faces:
        for tri in ((a, b, c), (a, c, d)):
            p0, p1, p2 = corners[list(tri)]
            normal = np.cross(p1 - p0, p2 - p0)
            if np.dot(normal, centre - p0) < 0:          # make the face look into the room
                tri = (tri[0], tri[2], tri[1])
            tris.append(tri)
    return corners.astype(np.float32), np.array(tris, dtype=np.uint16)


WALLS = ("x_min", "x_max", "y_min", "y_max", "z_min", "z_max")   # world frame; z_min is the floor


def wall_of_triangle(verts_gltf, tri):
    """Which of WALLS a triangle lies on: the world axis its corners share, and at which bound."""
    world = (GLTF_TO_WORLD @ verts_gltf[list(tri)].astype(float).T).T
    for k in range(3):
        if np.ptp(world[:, k]) == 0:
            return 2 * k + int(abs(world[0, k] - BOX_MAX_M[k]) < abs(world[0, k] - BOX_MIN_M[k]))
    raise AssertionError("a box triangle off every wall")


def wall_material(name, reflectivity):
    return {"name": name, "doubleSided": True,
            "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extras": {"reflectivity": reflectivity}}


def write_gltf(path, wall_reflectivity=None):
    """One mesh and material for the whole room (reflectivity 0.5); with wall_reflectivity (six values,
    in WALLS' order), one mesh, node and material per wall, sharing the corners' accessor."""
    verts, tris = box_triangles_gltf()
    if wall_reflectivity is not None:                   # the triangles grouped by wall, in WALLS' order
        walls = [wall_of_triangle(verts, tri) for tri in tris]
        tris = np.array([tris[i] for w in range(6) for i in range(len(tris)) if walls[i] == w], dtype=np.uint16)
        assert sorted(walls) == [w for w in range(6) for _ in range(2)]
    vbytes, ibytes = verts.tobytes(), tris.tobytes()
    blob = vbytes + ibytes                               # 96 B of positions is 4-byte aligned
    positions = {"bufferView": 0, "componentType": 5126, "count": len(verts), "type": "VEC3",
                 "min": verts.min(axis=0).tolist(), "max": verts.max(axis=0).tolist()}
    if wall_reflectivity is None:
        nodes = [{"name": "room", "mesh": 0}]
        meshes = [{"name": "room", "primitives": [
            {"attributes": {"POSITION": 0}, "indices": 1, "material": 0, "mode": 4}]}]
        materials = [wall_material("wall", 0.5)]
        accessors = [positions, {"bufferView": 1, "componentType": 5123, "count": tris.size, "type": "SCALAR"}]
    else:
        nodes = [{"name": f"wall_{w}", "mesh": i} for i, w in enumerate(WALLS)]
        meshes = [{"name": f"wall_{w}", "primitives": [
            {"attributes": {"POSITION": 0}, "indices": 1 + i, "material": i, "mode": 4}]}
            for i, w in enumerate(WALLS)]
        materials = [wall_material(f"wall_{w}", float(r)) for w, r in zip(WALLS, wall_reflectivity)]
        accessors = [positions] + [{"bufferView": 1, "byteOffset": i * 6 * 2, "componentType": 5123,
                                    "count": 6, "type": "SCALAR"} for i in range(6)]
    doc = {
        "asset": {"version": "2.0", "generator": "lidartwin independent_capture.py"},
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(blob).decode("ascii")}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(vbytes), "target": 34962},
            {"buffer": 0, "byteOffset": len(vbytes), "byteLength": len(ibytes), "target": 34963}],
        "accessors": accessors,
    }
    with open(path, "w") as f:
        json.dump(doc, f, indent=1)


def write_pose(path, motion, frames):
    """TUM world_from_sensor. A static sensor: one line at t = 0 (a fixed pose). A moving one: a knot
    at each frame's first column and one where the last frame ends, stamped in seconds on the
    column-timestamp clock; between knots the motion is linear in t (translation) and one rotation
    about world Z at a constant rate (SLERP), so interpolating the knots reproduces it exactly."""
    with open(path, "w") as f:
        if not motion.moving:
            if np.any(motion.start != 0):
                f.write(f"0 {motion.start[0]!r} {motion.start[1]!r} {motion.start[2]!r} 0 0 0 1\n")
            else:
                f.write("0 0 0 0 0 0 0 1\n")
            return
        knots_ns = T0_NS + np.arange(frames + 1, dtype=np.int64) * FRAME_NS
        _, pos_m, yaw = motion.at_ns(knots_ns)
        for ts, p, a in zip(knots_ns, pos_m, yaw):
            q = (0.0, 0.0, float(np.sin(a / 2)), float(np.cos(a / 2)))     # x y z w, about world Z
            f.write(f"{int(ts) // 1_000_000_000}.{int(ts) % 1_000_000_000:09d} "
                    + " ".join(repr(float(v)) for v in (*p, *q)) + "\n")


# ---------------------------------------------------------------- geometry (7.1, 7.2)
def beam_rays(meta):
    """Section 7.1 for every (row r, measurement id m): ray origin O_s (mm) and unit direction D_s in
    the sensor frame, arrays of shape (H, W, 3). The SDK's point is p_mm = range_mm * D_s + O_s."""
    bi = meta["beam_intrinsics"]
    B = np.array(bi["beam_to_lidar_transform"], dtype=float).reshape(4, 4)
    T = np.array(meta["lidar_intrinsics"]["lidar_to_sensor_transform"], dtype=float).reshape(4, 4)
    az = np.radians(np.array(bi["beam_azimuth_angles"]))[:, None]
    alt = np.radians(np.array(bi["beam_altitude_angles"]))[:, None]
    m = np.arange(W)[None, :]
    theta_e = 2 * np.pi - m * 2 * np.pi / W
    theta_a = -az
    n = B[0, 3] if B[2, 3] == 0 else np.hypot(B[0, 3], B[2, 3])
    d = np.stack(np.broadcast_arrays(np.cos(theta_e + theta_a) * np.cos(alt),
                                     np.sin(theta_e + theta_a) * np.cos(alt),
                                     np.sin(alt)), axis=-1)
    o = np.stack(np.broadcast_arrays(B[0, 3] * np.cos(theta_e) - n * d[..., 0],
                                     B[0, 3] * np.sin(theta_e) - n * d[..., 1],
                                     B[2, 3] - n * d[..., 2]), axis=-1)
    R, t = T[:3, :3], T[:3, 3]
    return o @ R.T + t, d @ R.T


def box_exit(origin, direction, lo, hi):
    """Distance along unit `direction` from `origin` (inside the box) to the first wall (slab method),
    the cosine of the incidence there (the wall's normal is the axis the ray leaves by) and which wall
    it is (WALLS: 2 * axis + 1 if the ray leaves through the axis' upper bound)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(direction > 0, hi, lo)
        t = np.where(direction != 0, (bound - origin) / direction, np.inf)
    axis = t.argmin(axis=-1)
    along = np.take_along_axis(direction, axis[..., None], axis=-1)[..., 0]
    wall = 2 * axis + (along > 0)
    return t.min(axis=-1), np.abs(along), wall


class Motion:
    """The sensor's ground-truth motion: world_from_sensor(t) = (R(t), p(t)) with
    p(t) = start + velocity * (t - t0) and R(t) the rotation by yaw_rate * (t - t0) about world Z,
    t0 the capture's first column (T0_NS). Times are the column-timestamp clock (ns or s)."""

    def __init__(self, velocity_mps, yaw_rate_deg_s, start_m):
        self.velocity = np.array(velocity_mps, dtype=float)
        self.yaw_rate = np.radians(yaw_rate_deg_s)
        self.start = np.array(start_m, dtype=float)
        self.moving = bool(np.any(self.velocity != 0) or self.yaw_rate != 0)

    def at_ns(self, ts_ns):
        """Rotations (..., 3, 3), positions (..., 3) in metres and yaw angles (rad) at column times (ns)."""
        dt = (np.asarray(ts_ns, dtype=np.int64) - T0_NS) / 1e9
        yaw = self.yaw_rate * dt
        c, s = np.cos(yaw), np.sin(yaw)
        zero, one = np.zeros_like(yaw), np.ones_like(yaw)
        rot = np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1),
                        np.stack([zero, zero, one], -1)], -2)
        return rot, self.start + dt[..., None] * self.velocity, yaw

    def check_inside_room(self, frames, margin_m=0.5):
        """The sensor must stay at least margin_m inside every wall from the first column to the end of
        the last frame; otherwise exit with a message saying when and where it leaves."""
        t_end_s = frames * FRAME_NS / 1e9
        first = None                                      # (seconds after t0, axis, wall coordinate)
        for k, axis in enumerate("xyz"):
            for wall_m, limit, sign in ((BOX_MIN_M[k], BOX_MIN_M[k] + margin_m, 1.0),
                                        (BOX_MAX_M[k], BOX_MAX_M[k] - margin_m, -1.0)):
                inside = sign * (self.start[k] - limit)   # >= 0 while at least margin_m from the wall
                rate = sign * self.velocity[k]
                if inside < 0:
                    t = 0.0
                elif rate < 0 and inside / -rate < t_end_s:
                    t = inside / -rate
                else:
                    continue
                if first is None or t < first[0]:
                    first = (t, axis, wall_m)
        if first is None:
            return
        t, axis, wall_m = first
        at = self.start + t * self.velocity
        raise SystemExit(
            f"independent_capture.py: the motion leaves the room: {t:.4f} s after the first column "
            f"(capture clock {T0_NS / 1e9 + t:.4f} s) the sensor is at ({at[0]:.3f}, {at[1]:.3f}, {at[2]:.3f}) m, "
            f"within {margin_m} m of the wall {axis} = {wall_m:g} m. The room is x [{BOX_MIN_M[0]:g}, "
            f"{BOX_MAX_M[0]:g}], y [{BOX_MIN_M[1]:g}, {BOX_MAX_M[1]:g}], z [{BOX_MIN_M[2]:g}, {BOX_MAX_M[2]:g}] m "
            f"and the capture lasts {t_end_s:g} s; use fewer --frames, a lower --velocity or another --start.")


def true_ranges_mm(rays, motion, frame):
    """Noise-free range (mm, float), the incidence's cosine and the wall hit per (row, measurement id)
    of one frame. Each column is cast from the pose at its own timestamp (protocol doc 6.1, 7.2): its
    ray (O_s, D_s) goes to the world as R(t) O_s + p(t), R(t) D_s. A static sensor at the origin
    casts the sensor-frame rays as they are (the sensor frame is the world frame)."""
    origin, direction = rays
    if motion.moving or np.any(motion.start != 0):
        rot, pos_m, _ = motion.at_ns(column_timestamp_ns(frame, np.arange(W)))
        origin = np.einsum("wij,hwj->hwi", rot, origin) + pos_m[None, :, :] * 1000.0
        direction = np.einsum("wij,hwj->hwi", rot, direction)
    return box_exit(origin, direction, BOX_MIN_M * 1000.0, BOX_MAX_M * 1000.0)


class Radiometry:
    """lidar-physics.md 2.2: the expected signal and ambient of each pixel, this generator's constants."""
    GAIN, OVERLAP_M, OVERLAP_EXPONENT, AMBIENT, RHO = 2.2e5, 5.0, 3.0, 30.0, 0.5   # RHO: the walls' default

    def __init__(self, true_mm, cos_incidence, rho):
        """rho: each pixel's diffuse reflectivity (its wall's)."""
        r_m = true_mm / 1000.0
        overlap = 1.0 / (1.0 + (self.OVERLAP_M / r_m) ** self.OVERLAP_EXPONENT)
        self.rho_app = rho * cos_incidence
        self.signal = self.GAIN * self.rho_app * overlap / r_m ** 2
        self.ambient = self.AMBIENT * rho

    @classmethod
    def truth(cls):
        return {"gain_photons_m2": cls.GAIN, "overlap_range_m": cls.OVERLAP_M,
                "overlap_exponent": cls.OVERLAP_EXPONENT, "ambient_photons": cls.AMBIENT}


class Hidden:
    """The hidden effects (lidar-physics.md E2, E4, E5, E10, E12) of one capture."""

    def __init__(self, args):
        self.snr_k = args.snr_k
        self.threshold, self.width = args.detect_threshold, args.detect_width
        self.divergence = args.divergence
        unit = np.random.default_rng(args.beam_seed)
        self.beam_offset_m = unit.standard_normal(H) * args.beam_offset_sigma
        self.beam_scale = unit.standard_normal(H) * args.beam_scale_sigma
        for beam, offset_m in args.beam_offset or []:
            if not 0 <= int(beam) < H:
                raise SystemExit(f"independent_capture.py: --beam-offset: beam {beam} is not one of 0..{H - 1}")
            self.beam_offset_m[int(beam)] += offset_m
        self.mu0, self.muinf, self.tau = args.drift_mu0, args.drift_muinf, args.drift_tau
        self.tail_p, self.tail_half, self.tail_sigma = args.tail_probability, args.tail_half_signal, args.tail_sigma

    def truth(self):
        return {"snr_k_m": self.snr_k, "detect_threshold_photons": self.threshold, "detect_width": self.width,
                "divergence_rad": self.divergence,
                "beam_offsets_m": self.beam_offset_m.tolist(), "beam_scales": self.beam_scale.tolist(),
                "drift_mu0_m": self.mu0, "drift_muinf_m": self.muinf, "drift_tau_s": self.tau,
                "tail_probability": self.tail_p, "tail_half_signal_photons": self.tail_half,
                "tail_sigma_m": self.tail_sigma}

    def tail_m(self, radiometry, rng):
        """E2's tails: the extra range error of the returns drawn into the wider Gaussian (none drawn
        when off, so that the other effects' captures stay as they were)."""
        if self.tail_p <= 0:
            return 0.0
        share = self.tail_p / (1.0 + radiometry.signal / self.tail_half)
        in_tail = rng.random(share.shape) < share
        return np.where(in_tail, rng.standard_normal(share.shape) * self.tail_sigma, 0.0)

    def variance_m2(self, true_m, cos_incidence, radiometry):
        """E4: the footprint's, (r tan(theta) gamma / 2.355)^2; E2: k^2 (S + B) / S^2."""
        tan = np.sqrt(np.maximum(1.0 - cos_incidence ** 2, 0.0)) / np.maximum(cos_incidence, 1e-9)
        footprint = true_m * np.minimum(tan, 20.0) * self.divergence / 2.355
        s = np.maximum(radiometry.signal, 1.0)
        return footprint ** 2 + self.snr_k ** 2 * (s + radiometry.ambient) / s ** 2

    def detected(self, radiometry, rng):
        """E5: which returns are reported."""
        if self.threshold <= 0:
            return np.ones(radiometry.signal.shape, dtype=bool)
        x = (np.log(radiometry.signal) - np.log(self.threshold)) / self.width
        return rng.random(radiometry.signal.shape) < 1.0 / (1.0 + np.exp(-x))

    def mean_m(self, true_m, frame):
        """E10 per beam (rows) and E12 per column time."""
        per_beam = (1.0 + self.beam_scale[:, None]) * true_m + self.beam_offset_m[:, None]
        t_s = (column_timestamp_ns(frame, np.arange(W)) - T0_NS) / 1e9
        drift = self.muinf + (self.mu0 - self.muinf) * np.exp(-t_s / self.tau) if self.tau > 0 else 0.0
        return per_beam + np.broadcast_to(drift, (W,))[None, :]


def measured_ranges_mm(true_mm, cos_incidence, radiometry, rng, sigma0, slope, hidden, frame):
    """Add N(0, sigma0 + slope * R_m) metres of noise (and the hidden effects), round to whole mm,
    clip to the 19-bit field."""
    true_m = true_mm / 1000.0
    sigma_m = np.sqrt((sigma0 + slope * true_m) ** 2 + hidden.variance_m2(true_m, cos_incidence, radiometry))
    noisy_m = hidden.mean_m(true_m, frame) + rng.standard_normal(true_mm.shape) * sigma_m
    noisy_m = noisy_m + hidden.tail_m(radiometry, rng)
    return np.clip(np.rint(noisy_m * 1000.0), 1, 0x7FFFF).astype(np.uint32)


def measured_channels(radiometry, rng):
    """SIGNAL ~ Poisson(S), NEAR_IR ~ Poisson(B), REFLECTIVITY = round(100 rho_app), clipped to their fields."""
    signal = np.clip(rng.poisson(radiometry.signal), 1, 65535).astype(np.uint16)
    nir = np.clip(rng.poisson(radiometry.ambient), 0, 65535).astype(np.uint16)
    refl = np.clip(np.rint(100.0 * radiometry.rho_app), 0, 100).astype(np.uint8)
    return signal, refl, nir


# ---------------------------------------------------------------- lidar packets (4.3 - 4.6)
PIXEL_DTYPE = np.dtype([("range", "<u4"), ("refl", "u1"), ("pad0", "u1"), ("signal", "<u2"),
                        ("nir", "<u2"), ("pad1", "u1"), ("window", "u1")])
assert PIXEL_DTYPE.itemsize == PIXEL_BYTES


def column_timestamp_ns(frame, mid):
    return T0_NS + frame * FRAME_NS + mid * FRAME_NS // W


def packet_header(frame_id):
    """STANDARD 32-byte header: packet_type 1, frame_id, init_id (24 b) and prod_sn (40 b), rest 0."""
    ids = (INIT_ID & 0xFFFFFF) | (int(PROD_SN) << 24)
    return struct.pack("<HHQ", 1, frame_id & 0xFFFF, ids) + bytes(20)


def column_block(ts_ns, mid, ranges_mm, signal, refl, nir):
    """12-byte column header (timestamp, measurement_id, status bit0 = valid) + H pixels, row 0 first."""
    px = np.zeros(H, dtype=PIXEL_DTYPE)
    px["range"] = ranges_mm & 0x7FFFF                      # bits 0-18; FLAGS bits 19-23 stay 0
    px["refl"] = refl
    px["signal"] = signal
    px["nir"] = nir
    return struct.pack("<QHH", ts_ns, mid, 0x0001) + px.tobytes()


def lidar_packet(frame, first_mid, ranges_mm, signal, refl, nir):
    """One 12544-byte lidar packet: columns first_mid .. first_mid+15 of the (H, W) channels."""
    parts = [packet_header(frame)]
    for mid in range(first_mid, first_mid + CPP):
        parts.append(column_block(column_timestamp_ns(frame, mid), mid,
                                  ranges_mm[:, mid], signal[:, mid], refl[:, mid], nir[:, mid]))
    body = b"".join(parts) + bytes(24)                      # footer: 24 reserved bytes + CRC
    packet = body + struct.pack("<Q", crc64_xz(body))
    assert len(packet) == PACKET_BYTES
    return packet


# ---------------------------------------------------------------- Ethernet / IPv4 / UDP / pcap
def ones_complement_sum(data):
    if len(data) % 2:
        data += b"\0"
    total = int(np.frombuffer(data, dtype=">u2").astype(np.uint64).sum())
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return total


def ip_bytes(dotted):
    return bytes(int(x) for x in dotted.split("."))


def udp_frame(payload, ident):
    """Ethernet II + IPv4 (DF set, no fragmentation, correct checksum) + UDP (correct checksum)."""
    src, dst = ip_bytes(SRC_IP), ip_bytes(DST_IP)
    udp_len = 8 + len(payload)
    pseudo = src + dst + struct.pack("!BBH", 0, 17, udp_len)
    udp_nock = struct.pack("!HHHH", LIDAR_PORT, LIDAR_PORT, udp_len, 0)
    udp_ck = 0xFFFF - ones_complement_sum(pseudo + udp_nock + payload)
    udp = struct.pack("!HHHH", LIDAR_PORT, LIDAR_PORT, udp_len, udp_ck or 0xFFFF)
    ip_nock = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + udp_len, ident & 0xFFFF, 0x4000,
                          64, 17, 0, src, dst)
    ip_ck = 0xFFFF - ones_complement_sum(ip_nock)
    ip = ip_nock[:10] + struct.pack("!H", ip_ck) + ip_nock[12:]
    return DST_MAC + SRC_MAC + b"\x08\x00" + ip + udp + payload


def pcap_global_header():
    # magic 0xa1b2c3d4 (microseconds), v2.4, thiszone 0, sigfigs 0, snaplen 262144, linktype 1
    return struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 262144, 1)


def pcap_record(ts_ns, frame_bytes):
    sec, usec = ts_ns // 1_000_000_000, (ts_ns % 1_000_000_000) // 1000
    return struct.pack("<IIII", sec, usec, len(frame_bytes), len(frame_bytes)) + frame_bytes


def frame_truth(rays, motion, wall_rho, frame):
    true_mm, cos_incidence, wall = true_ranges_mm(rays, motion, frame)
    return true_mm, cos_incidence, Radiometry(true_mm, cos_incidence, wall_rho[wall])


def write_pcap(path, meta, frames, rng, channel_rng, sigma0, slope, hidden, motion, wall_rho):
    """rng: the range noise; channel_rng: SIGNAL, NEAR_IR and detection (their own stream, so that
    a seed gives the same range noise whichever channels are drawn). A moving sensor's frames are
    each cast from their own columns' poses; a static sensor's once."""
    rays = beam_rays(meta)
    true_mm, cos_incidence, radiometry = frame_truth(rays, motion, wall_rho, 0)
    ident = 0
    with open(path, "wb") as f:
        f.write(pcap_global_header())
        for frame in range(frames):
            if motion.moving and frame > 0:
                true_mm, cos_incidence, radiometry = frame_truth(rays, motion, wall_rho, frame)
            ranges = measured_ranges_mm(true_mm, cos_incidence, radiometry, rng, sigma0, slope, hidden, frame)
            signal, refl, nir = measured_channels(radiometry, channel_rng)
            lost = ~hidden.detected(radiometry, channel_rng)
            ranges[lost], signal[lost], refl[lost] = 0, 0, 0
            for first_mid in range(0, W, CPP):
                packet = lidar_packet(frame, first_mid, ranges, signal, refl, nir)
                f.write(pcap_record(column_timestamp_ns(frame, first_mid), udp_frame(packet, ident)))
                ident += 1
    return ident


# ---------------------------------------------------------------- main
def parse_args():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out_dir")
    p.add_argument("--frames", type=int, default=10)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--sigma0", type=float, default=0.010, help="range noise at 0 m, metres")
    p.add_argument("--slope", type=float, default=0.0014, help="range noise growth, metres per metre")
    p.add_argument("--snr-k", type=float, default=0.0, help="E2: k, metres x sqrt(photons)")
    p.add_argument("--detect-threshold", type=float, default=0.0, help="E5: S_th, photons (0: off)")
    p.add_argument("--detect-width", type=float, default=0.3, help="E5: logistic width in ln S")
    p.add_argument("--divergence", type=float, default=0.0, help="E4: beam divergence (FWHM), rad")
    p.add_argument("--tail-probability", type=float, default=0.0, help="E2's tails: share as S -> 0")
    p.add_argument("--tail-half-signal", type=float, default=10.0, help="E2's tails: S where the share halves")
    p.add_argument("--tail-sigma", type=float, default=0.1, help="E2's tails: their extra spread, m")
    p.add_argument("--beam-offset-sigma", type=float, default=0.0, help="E10: per-beam offsets' sd, m")
    p.add_argument("--beam-scale-sigma", type=float, default=0.0, help="E10: per-beam scales' sd")
    p.add_argument("--beam-seed", type=int, default=7, help="E10: the unit")
    p.add_argument("--beam-offset", type=float, nargs=2, action="append", metavar=("BEAM", "METRES"),
                   help="E10: one beam's offset, added to its drawn one (repeatable)")
    p.add_argument("--drift-mu0", type=float, default=0.0, help="E12: common offset at t = 0, m")
    p.add_argument("--drift-muinf", type=float, default=0.0, help="E12: common offset after warm-up, m")
    p.add_argument("--drift-tau", type=float, default=0.0, help="E12: warm-up time constant, s (0: off)")
    p.add_argument("--velocity", type=float, nargs=3, default=[0.0, 0.0, 0.0], metavar=("VX", "VY", "VZ"),
                   help="the sensor's constant velocity, m/s, world frame")
    p.add_argument("--yaw-rate", type=float, default=0.0, metavar="DEG_PER_S",
                   help="the sensor's constant rotation rate about world Z, deg/s")
    p.add_argument("--start", type=float, nargs=3, default=[0.0, 0.0, 0.0], metavar=("X", "Y", "Z"),
                   help="the sensor's position at the first column, m, world frame (orientation: the world's)")
    p.add_argument("--wall-reflectivity", type=float, nargs=6, default=None,
                   metavar=("X_MIN", "X_MAX", "Y_MIN", "Y_MAX", "Z_MIN", "Z_MAX"),
                   help="the walls' diffuse reflectivities (default: one material, 0.5)")
    args = p.parse_args()
    if args.frames < 1:
        p.error("--frames must be at least 1")
    if abs(args.yaw_rate) * FRAME_NS / 1e9 >= 180.0:
        p.error("--yaw-rate: the sensor must turn less than 180 deg per frame (the pose knots are one frame apart)")
    if args.wall_reflectivity is not None and not all(0 < r <= 1 for r in args.wall_reflectivity):
        p.error("--wall-reflectivity: each value must be in (0, 1]")
    return args


def main():
    args = parse_args()
    motion = Motion(args.velocity, args.yaw_rate, args.start)
    motion.check_inside_room(args.frames)
    os.makedirs(args.out_dir, exist_ok=True)
    wall_rho = np.array(args.wall_reflectivity if args.wall_reflectivity is not None else [Radiometry.RHO] * 6)
    meta = make_metadata()
    write_gltf(os.path.join(args.out_dir, "scene.gltf"), args.wall_reflectivity)
    write_pose(os.path.join(args.out_dir, "pose.tum"), motion, args.frames)
    with open(os.path.join(args.out_dir, "metadata.json"), "w") as f:
        json.dump(meta, f, indent=1)
    rng = np.random.default_rng(args.seed)
    hidden = Hidden(args)
    with open(os.path.join(args.out_dir, "truth.json"), "w") as f:
        truth = {**hidden.truth(), "radiometry": Radiometry.truth(),
                 "range_noise": {"sigma0_m": args.sigma0, "slope": args.slope}}
        if args.wall_reflectivity is not None:
            truth["wall_reflectivity"] = dict(zip(WALLS, args.wall_reflectivity))
        if motion.moving or np.any(motion.start != 0):
            truth["motion"] = {"velocity_mps": args.velocity, "yaw_rate_deg_s": args.yaw_rate,
                               "start_m": args.start, "t0_s": T0_NS / 1e9}
        json.dump(truth, f, indent=1)
    channel_rng = np.random.default_rng([args.seed, 1])
    n = write_pcap(os.path.join(args.out_dir, "capture.pcap"), meta, args.frames, rng, channel_rng,
                   args.sigma0, args.slope, hidden, motion, wall_rho)
    print("scene: scene.gltf")
    print(f"wrote scene.gltf, pose.tum, metadata.json, capture.pcap ({n} lidar packets of "
          f"{PACKET_BYTES} B, {args.frames} frames) to {args.out_dir}")


if __name__ == "__main__":
    main()
