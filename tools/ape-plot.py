#!/usr/bin/python3
"""ape.json of `lidartwin ape` -> ape.png: the translation error over time, with its statistics.

Usage: tools/ape-plot.py DIR   (Debian's python3 with matplotlib)
"""
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    directory = Path(sys.argv[1])
    ape = json.loads((directory / "ape.json").read_text())
    t0 = ape["times_s"][0] if ape["times_s"] else 0.0
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.plot([t - t0 for t in ape["times_s"]], ape["errors_m"], color="#4477aa", lw=1, label="APE (m)")
    for name, colour in (("rmse_m", "#cc3311"), ("mean_m", "#228833"), ("median_m", "#ee7733")):
        ax.axhline(ape[name], color=colour, lw=1, ls="--", label="%s %.3f" % (name[:-2], ape[name]))
    ax.set_xlabel("time since the first pair, s")
    ax.set_ylabel("translation error, m")
    ax.set_title("APE, %s alignment, %d pairs" % (ape["alignment"], ape["pairs"]), fontsize=10)
    ax.legend(fontsize=8)
    fig.savefig(directory / "ape.png", dpi=90, bbox_inches="tight")


if __name__ == "__main__":
    main()
