#!/usr/bin/env python3
"""Lidar odometry with Open3D on the frames `lidartwin points` exports: the paper's experiment
(LeGO-LOAM scored with evo's APE) with a registration library anyone can install from Debian.

  tools/lidar-odometry.py frames.npz --out odometry.tum [--deskew]

Each frame is registered to a local map of the last --map-frames frames (point-to-plane ICP,
Tukey-robust, from a constant-velocity guess); the map grows in the world frame of the first frame.
With --deskew every point is first moved to where the sensor was at the middle of its frame, using
its column timestamp and the motion estimated between the two previous frames (constant velocity),
as KISS-ICP does; the middle, because an error in the velocity then distorts both halves of the
frame alike instead of tilting it (deskewing to the first column feeds a rate error back into the
next estimate and oscillates). Without it the frame is taken as a rigid snapshot.
The output is TUM: the sensor's pose at each frame's first column timestamp (as ouster-ros stamps
a scan), in the first frame's sensor frame; evo or `lidartwin ape` align it to ground truth.
Needs python3-open3d and numpy (Debian packages).
"""
import argparse
import sys

import numpy as np

try:
    import open3d as o3d
except ImportError:  # pragma: no cover
    sys.exit("lidar-odometry.py: needs Open3D (apt install python3-open3d)")


def rotation_from_vector(w):
    """Rodrigues: rotation matrices for rotation vectors w (N x 3)."""
    theta = np.linalg.norm(w, axis=1)[:, None]
    small = theta[:, 0] < 1e-12
    k = np.where(small[:, None], 0.0, w / np.where(theta == 0, 1, theta))
    kx, ky, kz = k[:, 0], k[:, 1], k[:, 2]
    zero = np.zeros_like(kx)
    K = np.stack([np.stack([zero, -kz, ky], 1), np.stack([kz, zero, -kx], 1), np.stack([-ky, kx, zero], 1)], 1)
    s, c = np.sin(theta)[:, :, None], np.cos(theta)[:, :, None]
    return np.eye(3)[None] + s * K + (1 - c) * (K @ K)


def vector_from_rotation(R):
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))
    if angle < 1e-12:
        return np.zeros(3)
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2 * np.sin(angle))
    return axis * angle


def motion(velocity, dt):
    """The sensor's motion over dt under constant velocity, as a 4 x 4 transform."""
    w, v = velocity
    T = np.eye(4)
    T[:3, :3] = rotation_from_vector(w[None, :] * dt)[0]
    T[:3, 3] = v * dt
    return T


def deskew(points, times, t0, velocity):
    """Moves each point to the sensor frame at t0 under constant velocity.

    velocity: (rotation vector per s, translation per s), both in the sensor frame at t0, i.e. the
    motion T(dt) = [R(w dt), v dt] of the sensor from t0 to t0 + dt.
    """
    w, v = velocity
    dt = (times - t0)[:, None]
    R = rotation_from_vector(w[None, :] * dt)
    return np.einsum("nij,nj->ni", R, points) + v[None, :] * dt


def to_tum_row(t, T):
    R, p = T[:3, :3], T[:3, 3]
    q = quaternion_from_matrix(R)
    return f"{t:.9f} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f} {q[0]:.9f} {q[1]:.9f} {q[2]:.9f} {q[3]:.9f}\n"


def quaternion_from_matrix(R):
    w = np.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = np.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2
    y = np.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2
    z = np.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2
    x = np.copysign(x, R[2, 1] - R[1, 2])
    y = np.copysign(y, R[0, 2] - R[2, 0])
    z = np.copysign(z, R[1, 0] - R[0, 1])
    return x, y, z, w


def cloud(points, voxel):
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pc = pc.voxel_down_sample(voxel)
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=3 * voxel, max_nn=20))
    return pc


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("frames", help="the .npz of `lidartwin points`")
    p.add_argument("--out", required=True, help="the estimated trajectory, TUM")
    p.add_argument("--deskew", action="store_true", help="deskew with the column timestamps")
    p.add_argument("--voxel", type=float, default=0.3, help="voxel size of the frames and the map, m")
    p.add_argument("--map-frames", type=int, default=10, help="frames in the local map")
    p.add_argument("--min-range", type=float, default=1.0, help="drop points closer than this (the drone), m")
    args = p.parse_args()

    data = np.load(args.frames)
    xyz = data["xyz"].reshape(-1, 3).astype(np.float64)
    times = data["t_s"]
    offsets = data["frame_offsets"]
    frame_times = data["frame_t_s"]
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)

    poses = []  # world_from_sensor at the time each frame is registered at (the middle, deskewed)
    starts = []  # world_from_sensor at each frame's first column
    local_map = []
    delta = np.eye(4)  # sensor(k-1) -> sensor(k), the constant-velocity guess
    velocity = (np.zeros(3), np.zeros(3))
    criteria = o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=30, relative_fitness=1e-7,
                                                                 relative_rmse=1e-7)
    estimation = o3d.pipelines.registration.TransformationEstimationPointToPlane(
        o3d.pipelines.registration.TukeyLoss(k=args.voxel))
    for k in range(len(frame_times)):
        points, t = xyz[offsets[k]:offsets[k + 1]], times[offsets[k]:offsets[k + 1]]
        keep = np.linalg.norm(points, axis=1) > args.min_range
        points, t = points[keep], t[keep]
        # Deskewed, a frame is registered at its middle; raw, its points are taken as they are.
        reference_t = 0.5 * (t.min() + t.max()) if args.deskew else frame_times[k]
        if args.deskew:
            points = deskew(points, t, reference_t, velocity)
        source = cloud(points, args.voxel)
        if not poses:
            pose = np.eye(4)
        else:
            guess = poses[-1] @ delta
            target = o3d.geometry.PointCloud()
            target.points = o3d.utility.Vector3dVector(np.vstack([np.asarray(c.points) for c in local_map]))
            target.normals = o3d.utility.Vector3dVector(np.vstack([np.asarray(c.normals) for c in local_map]))
            target = target.voxel_down_sample(args.voxel)  # overlapping frames: one point per voxel
            pose = o3d.pipelines.registration.registration_icp(source, target, 2 * args.voxel, guess, estimation,
                                                               criteria).transformation
            delta = np.linalg.inv(poses[-1]) @ pose
            dt = reference_t - previous_t
            velocity = (vector_from_rotation(delta[:3, :3]) / dt, delta[:3, 3] / dt)
        poses.append(pose)
        previous_t = reference_t
        starts.append(pose @ np.linalg.inv(motion(velocity, reference_t - frame_times[k])))
        local_map.append(source.transform(pose.copy()))
        local_map = local_map[-args.map_frames:]
    with open(args.out, "w") as f:
        f.write("# lidar-odometry.py: world_from_sensor at each frame's first column (world = frame 0)\n")
        for t, T in zip(frame_times, starts):
            f.write(to_tum_row(t, T))
    print(f"lidar-odometry.py: {len(poses)} frames, deskew {'on' if args.deskew else 'off'} -> {args.out}")


if __name__ == "__main__":
    main()
