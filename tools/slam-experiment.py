#!/usr/bin/env python3
"""The paper's Table II experiment on lidartwin: fly the yard lap (scenes/yard.glb,
scenes/yard_flight.tum) with several sensor profiles, run an Open3D lidar odometry
(tools/lidar-odometry.py) with and without deskewing, and score it with `lidartwin ape` (evo's
APE, SE(3) alignment) against the recorded per-column ground truth.

  tools/slam-experiment.py [--lidartwin build/src/lidartwin] [--out out/slam] [--frames 0]
                           [--runs ideal:os0-32-paper,os0-32-paper,ideal:os1-32-paper,os1-32-paper,os1-32]

A run is PROFILE or ideal:PROFILE (recorded with --ideal: no noise). Prints one table row per run
and writes OUT/table.json. Needs python3-open3d and numpy (Debian packages).
"""
import argparse
import json
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(command):
    result = subprocess.run(command, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"slam-experiment.py: {' '.join(command)} failed:\n{result.stdout}{result.stderr}")
    return result.stdout


def ape_rmse(lidartwin, reference, estimate):
    out = run([lidartwin, "ape", "--reference", reference, "--estimate", estimate, "--align", "se3",
               "--max-diff", "0.001"])
    values = dict(re.findall(r"^\s*(\w+)\s+([-0-9.]+)$", out, re.M))
    return {k: float(values[k]) for k in ("rmse", "mean", "median", "max")}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--lidartwin", default=os.path.join(ROOT, "build", "src", "lidartwin"))
    p.add_argument("--out", default="out/slam")
    p.add_argument("--frames", type=int, default=0, help="frames to record (0: the whole lap)")
    p.add_argument("--runs", default="ideal:os0-32-paper,os0-32-paper,ideal:os1-32-paper,os1-32-paper,os1-32")
    p.add_argument("--mode", default="512x10", help="every run's lidar_mode (the paper profiles have 512x10, 512x20)")
    p.add_argument("--seed", default="1")
    args = p.parse_args()

    scene = os.path.join(ROOT, "scenes", "yard.glb")
    flight = os.path.join(ROOT, "scenes", "yard_flight.tum")
    frames = args.frames
    if frames == 0:
        with open(flight) as f:
            last = [line for line in f if line.strip() and not line.startswith("#")][-1]
        frames = int(float(last.split()[0]) * 10)  # 10 Hz modes; the lap ends hovering
    rows = []
    print(f"{'run':<22} {'deskew':<7} {'APE rmse (m)':>12} {'mean':>8} {'median':>8} {'max':>8}")
    for spec in args.runs.split(","):
        ideal = spec.startswith("ideal:")
        profile = spec.split(":")[-1]
        directory = os.path.join(args.out, spec.replace(":", "-"))
        record = [args.lidartwin, "record", "--profile", profile, "--scene", scene, "--trajectory", flight,
                  "--mode", args.mode, "--frames", str(frames), "--seed", args.seed, "--out", directory]
        run(record + (["--ideal"] if ideal else []))
        npz = os.path.join(directory, "frames.npz")
        run([args.lidartwin, "points", "--capture", os.path.join(directory, "capture.pcap"), "--metadata",
             os.path.join(directory, "metadata.json"), "--out", npz])
        for deskew in (False, True):
            estimate = os.path.join(directory, f"odometry{'_deskewed' if deskew else ''}.tum")
            run([sys.executable, os.path.join(ROOT, "tools", "lidar-odometry.py"), npz, "--out", estimate]
                + (["--deskew"] if deskew else []))
            ape = ape_rmse(args.lidartwin, os.path.join(directory, "column_poses.tum"), estimate)
            rows.append({"run": spec, "deskew": deskew, **ape})
            print(f"{spec:<22} {'yes' if deskew else 'no':<7} {ape['rmse']:>12.4f} {ape['mean']:>8.4f} "
                  f"{ape['median']:>8.4f} {ape['max']:>8.4f}", flush=True)
    with open(os.path.join(args.out, "table.json"), "w") as f:
        json.dump(rows, f, indent=2)


if __name__ == "__main__":
    main()
