#!/usr/bin/env python3
"""Send live poses to `lidartwin serve --pose-udp PORT` (docs/live-poses.md), as a HIL rig would.

  tools/send-poses.py --port 9000 --circle 5 --speed 2        # drive a 5 m circle at 2 m/s
  tools/send-poses.py --port 9000 --tum flight.tum            # replay a TUM trajectory in real time
  tools/send-poses.py --port 9000 --pose "0 0 1.5 0 0 0 1"    # stand still

Times are CLOCK_MONOTONIC (start the daemon with --pose-clock monotonic) unless --clock realtime.
Standard library only.
"""
import argparse
import math
import socket
import struct
import sys
import time

FORMAT = "<4sHHIIq3d4d3d3d"
HAS_VELOCITY, HAS_ANGULAR_RATE = 1, 2


def message(seq, time_ns, position, quaternion, velocity=None, angular_rate=None):
    flags = (HAS_VELOCITY if velocity else 0) | (HAS_ANGULAR_RATE if angular_rate else 0)
    return struct.pack(FORMAT, b"LTPS", 1, flags, seq, 0, time_ns, *position, *quaternion,
                       *(velocity or (0.0, 0.0, 0.0)), *(angular_rate or (0.0, 0.0, 0.0)))


def yaw_quaternion(yaw):
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def circle(radius, speed, height):
    rate = speed / radius

    def at(t):
        a = rate * t
        position = (radius * math.cos(a), radius * math.sin(a), height)
        velocity = (-speed * math.sin(a), speed * math.cos(a), 0.0)
        return position, yaw_quaternion(a + math.pi / 2), velocity, (0.0, 0.0, rate)
    return at


def tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                rows.append([float(v) for v in line.replace(",", " ").split()])
    if len(rows) < 2:
        sys.exit(f"{path}: needs at least two poses")
    t0, duration = rows[0][0], rows[-1][0] - rows[0][0]

    def at(t):
        t = t0 + math.fmod(t, duration)
        i = next(k for k in range(1, len(rows)) if rows[k][0] >= t)
        a, b = rows[i - 1], rows[i]
        f = (t - a[0]) / (b[0] - a[0])
        position = tuple(a[j] + f * (b[j] - a[j]) for j in (1, 2, 3))
        qa, qb = a[4:8], b[4:8]
        if sum(x * y for x, y in zip(qa, qb)) < 0:
            qb = [-x for x in qb]
        q = [x + f * (y - x) for x, y in zip(qa, qb)]  # nlerp: close to slerp at these rates
        n = math.sqrt(sum(x * x for x in q))
        return position, tuple(x / n for x in q), None, None
    return at


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--rate", type=float, default=100.0, help="messages per second")
    p.add_argument("--clock", choices=["monotonic", "realtime"], default="monotonic")
    p.add_argument("--duration", type=float, default=0.0, help="seconds (0: until Ctrl-C)")
    motion = p.add_mutually_exclusive_group(required=True)
    motion.add_argument("--circle", type=float, metavar="RADIUS")
    motion.add_argument("--tum", metavar="FILE")
    motion.add_argument("--pose", metavar='"x y z qx qy qz qw"')
    p.add_argument("--speed", type=float, default=1.0, help="m/s on the circle")
    p.add_argument("--height", type=float, default=1.5, help="m above the world origin on the circle")
    args = p.parse_args()

    if args.circle:
        at = circle(args.circle, args.speed, args.height)
    elif args.tum:
        at = tum(args.tum)
    else:
        v = [float(x) for x in args.pose.split()]
        at = lambda t: (tuple(v[:3]), tuple(v[3:7]), None, None)  # noqa: E731
    now = time.monotonic_ns if args.clock == "monotonic" else time.time_ns
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    start, seq, period = now(), 0, 1.0 / args.rate
    try:
        while not args.duration or (now() - start) * 1e-9 < args.duration:
            t_ns = now()
            seq += 1
            sock.sendto(message(seq, t_ns, *at((t_ns - start) * 1e-9)), (args.host, args.port))
            time.sleep(max(0.0, period - (now() - t_ns) * 1e-9))
    except KeyboardInterrupt:
        pass
    print(f"sent {seq} poses", file=sys.stderr)


if __name__ == "__main__":
    main()
