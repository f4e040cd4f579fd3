#!/usr/bin/env python3
"""The spread ratio of a scene-based and a map-mode compare of one capture on the returns both
compared, per range and reflectivity bin of the scene's (its ideal range, its material's
reflectivity): the two reports bin different returns (map mode keeps returns on smooth surfaces
the other frames saw), so where the missing effect depends on more than the binned feature their
bins differ in what they hold, not in how they judge it. Each ratio is computed as compare's
misfit does: inliers (|z| <= 5 in both), sqrt(sum z^2 / n) for the scene and, for map mode, with
the reference's own variance taken out, s = v / sd^2: sqrt(sum w (z^2 - s) / (1 - s) / sum w), with
weights w = min(1, 2 (1 - s)). Per range bin also the median of map mode's incidence less the
scene's (degrees; the surface normal map mode estimates, on which E4's predicted spread rests).

usage: same_returns_spread.py SCENE_DIR MAP_DIR  ->  JSON on stdout
"""
import json
import sys

import numpy as np

OUTLIER_Z = 5.0
EDGES = {"range": [0, 1, 2, 3, 5, 8, 13, 20, 35, 60, 100, 200], "reflectivity": [0, 5, 10, 20, 40, 60, 80, 1e4]}


def main():
    scene = np.load(sys.argv[1] + "/pixels.npz")
    mapped = np.load(sys.argv[2] + "/pixels.npz")

    def key(d):
        return (d["frame"].astype(np.int64) << 32) | (d["column"].astype(np.int64) << 16) | d["beam"].astype(np.int64)

    _, js, jm = np.intersect1d(key(scene), key(mapped), return_indices=True)
    zs, zm = scene["z"][js], mapped["z"][jm]
    share = np.minimum(mapped["reference_variance_m2"][jm] / mapped["predicted_sd_m"][jm] ** 2, 1.0)
    weight = np.minimum(1.0 / np.maximum(1.0 - share, 1e-12), 2.0)  # w / (1 - s)
    inliers = (np.abs(zs) <= OUTLIER_Z) & (np.abs(zm) <= OUTLIER_Z) & (scene["range_m"][js] > 0)
    incidence = mapped["incidence_deg"][jm].astype(float) - scene["incidence_deg"][js].astype(float)
    features = {"range": scene["ideal_range_m"][js], "reflectivity": 100.0 * scene["material_reflectivity"][js]}
    out = {"returns": int(len(js))}
    for name, edges in EDGES.items():
        rows = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            s = inliers & (features[name] >= lo) & (features[name] < hi)
            if s.sum() == 0:
                continue
            row = {"bin": [lo, hi], "inliers": int(s.sum()),
                   "scene": float(np.sqrt(np.mean(zs[s] ** 2))),
                   "map": float(np.sqrt(np.sum(weight[s] * (zm[s] ** 2 - share[s])) /
                                        np.sum(weight[s] * (1.0 - share[s]))))}
            if name == "range":
                row["incidence_deg_map_less_scene"] = float(np.median(incidence[s]))
            rows.append(row)
        out[name] = rows
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
