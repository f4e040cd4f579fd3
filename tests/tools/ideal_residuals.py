#!/usr/bin/env python3
"""How an --ideal recording's measured ranges sit against the ideal ranges `compare` cast for the
same pixels (DIR/pixels.npz): an ideal recording's range is its ideal range on the wire's step, so
every return must lie within half a step of it, and every pixel the scene hits inside the
profile's range window must have returned. Prints JSON: counts per case, the largest difference,
and the columns and frames the table holds.

usage: ideal_residuals.py REPORT_DIR  ->  JSON on stdout
"""
import json
import sys

import numpy as np


def main():
    t = np.load(sys.argv[1] + "/pixels.npz")
    ideal, measured = t["ideal_range_m"], t["range_m"]
    hit, returned = ideal > 0, measured > 0
    inside = hit & (ideal >= t["window_min_m"]) & (ideal <= t["window_max_m"])
    both = hit & returned
    off = np.abs(measured - ideal)[both]
    json.dump({
        "pixels": int(len(ideal)),
        "returns": int(returned.sum()),
        "returns_without_a_hit": int((returned & ~hit).sum()),
        "hits_inside_without_a_return": int((inside & ~returned).sum()),
        "largest_difference_m": float(off.max()) if len(off) else 0.0,
        "beyond_half_a_step": int((off > 0.5 * t["step_m"][both] + 2e-5).sum()),
        "columns": int(len(np.unique(t["column"]))),
        "frames": int(len(np.unique(t["frame"]))),
    }, sys.stdout)


if __name__ == "__main__":
    main()
