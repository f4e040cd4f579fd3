#!/usr/bin/python3
"""report.json of `lidartwin compare` -> report.html, one self-contained page.

Usage: tools/compare-plots.py DIR   (DIR holds report.json; writes DIR/report.html)

Debian's python3-numpy and python3-matplotlib only. Every plot is a PNG embedded as base64, so
the page opens anywhere without the files next to it. The numbers come from report.json (its
schema: docs/compare-report.md), pixels.npz is not needed.
"""
import base64
import html
import os
import io
import json
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def png(fig):
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return '<img alt="plot" src="data:image/png;base64,%s">' % base64.b64encode(buffer.getvalue()).decode()


def bins_of(report, names):
    """The bins of one binning: those whose features are exactly `names`."""
    return [b for b in report["bins"] if sorted(b["features"]) == sorted(names)]


def count_label(n):
    return "%d" % n if n < 1000 else "%.0fk" % (n / 1000) if n < 1e6 else "%.1fM" % (n / 1e6)


# How a heat map or a range image signs each quantity (measured against the model), and what its
# colours mean: red where the measured value is above the model's.
DIRECTION = {
    "spread": (lambda b: math.log2(max(b["spread_ratio"], 1e-6)),
               ("log2(measured / model spread)", "red: the model too narrow, blue: too wide"),
               "wider than the model's (the model too narrow)", "narrower (the model too wide)"),
    "bias": (lambda b: 1000.0 * (b["bias_m"]["measured"] - b["bias_m"]["predicted"]),
             ("measured − model bias, mm", "red: measured longer, blue: shorter"),
             "longer than the model's", "shorter"),
    "detection": (lambda b: b["detection"]["measured"] - b["detection"]["predicted"],
                  ("measured − predicted return rate", "red: more returns than the model expects, blue: fewer"),
                  "returning more than the model expects", "less"),
    "outliers": (lambda b: b["outliers"]["measured"] - b["outliers"]["predicted"],
                 ("measured − predicted share beyond 5 sigma", "red: more outliers than expected, blue: fewer"),
                 "with more outliers than the model expects", "fewer"),
}


def heat_map(report, x, y, quantity, title):
    """Which way the model errs over two features: each cell whose test of `quantity` fails coloured
    by the signed difference (red: the measured value above the model's, blue: below), the others
    grey; each cell with its pixels."""
    bins = bins_of(report, [x, y])
    if not bins:
        return ""
    alpha = report["summary"]["alpha"]
    signed, label, above_words, below_words = DIRECTION[quantity]
    xs = sorted({tuple(b["features"][x]) for b in bins})
    ys = sorted({tuple(b["features"][y]) for b in bins})
    grid = np.full((len(ys), len(xs)), np.nan)
    quiet = np.full((len(ys), len(xs)), np.nan)
    counts = {}
    for b in bins:
        count = b["inliers"] if quantity in ("bias", "spread") else b["pixels"]
        cell = (ys.index(tuple(b["features"][y])), xs.index(tuple(b["features"][x])))
        counts[cell] = count
        if count <= 0:
            continue
        if b["p_value"][quantity] < alpha:
            grid[cell] = signed(b)
        else:
            quiet[cell] = 1.0
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    ax.imshow(quiet, origin="lower", aspect="auto", cmap=matplotlib.colors.ListedColormap(["#dddddd"]))
    limit = max(1e-6, np.nanmax(np.abs(grid))) if np.isfinite(grid).any() else 1.0
    image = ax.imshow(grid, origin="lower", aspect="auto", cmap="RdBu_r",
                      norm=matplotlib.colors.Normalize(vmin=-limit, vmax=limit))
    for (row, column), count in counts.items():
        strong = np.isfinite(grid[row, column]) and abs(grid[row, column]) > 0.6 * limit
        ax.text(column, row, count_label(count), ha="center", va="center", fontsize=7,
                color="white" if strong else "#222222")
    ax.set_xticks(range(len(xs)), ["%g–%g" % r for r in xs], rotation=45, ha="right", fontsize=7)
    ax.set_yticks(range(len(ys)), ["%g–%g" % r for r in ys], fontsize=7)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title("%s (grey: not significant at alpha %g; numbers: pixels)\n%s" % (title, alpha, label[1]), fontsize=9)
    bar = fig.colorbar(image, ax=ax)
    bar.set_label(label[0], fontsize=8)
    failing = int(np.isfinite(grid).sum())
    above = int((grid > 0).sum())
    caption = ('<p class="heat-map-caption">%d of %d cells fail in the %s: %d %s, %d %s; coloured by how far, the '
               'other %d grey.</p>' % (failing, len(counts), quantity, above, above_words, failing - above, below_words,
                                      len(counts) - failing))
    return png(fig) + caption


def residual_histograms(report):
    """Standardized range residuals per range band against the model's density (N(0, 1)), from
    report.json's residual_histograms (z counted in bins over [-6, 6])."""
    bands = report.get("residual_histograms")
    if not bands:
        return ""
    fig, axes = plt.subplots(1, len(bands), figsize=(12, 2.8), sharey=True)
    grid = np.linspace(-6, 6, 241)
    density = np.exp(-0.5 * grid ** 2) / math.sqrt(2 * math.pi)
    for ax, band in zip(axes, bands):
        counts = np.asarray(band["counts"], dtype=float)
        edges = np.linspace(band["z"][0], band["z"][1], counts.size + 1)
        if band["returns"]:
            ax.stairs(counts / (band["returns"] * (edges[1] - edges[0])), edges, fill=True, color="#4477aa",
                      label="measured")
        ax.plot(grid, density, color="#cc3311", label="model")
        ax.set_yscale("log")
        ax.set_ylim(1e-5, 1)
        lo, hi = band["range_m"]
        ax.set_title("range %g–%s m (%d returns)" % (lo, "∞" if hi > 1e3 else "%g" % hi, band["returns"]), fontsize=9)
        ax.set_xlabel("z")
    axes[0].legend(fontsize=8)
    return png(fig)


IMAGE_TITLES = {
    "bias": ("mean z of the returns (0 if the model is right)", "RdBu_r"),
    "spread": ("sd of z of the returns (1 if the model is right)", "viridis"),
    "detection": ("measured minus predicted return rate", "RdBu"),
    "outliers": ("share of returns beyond 5 sigma", "magma"),
}


def range_images(report):
    """One beam × azimuth image per failing quantity (report.json's range_image): where on the
    sensor's own picture the misfit lies."""
    image = report.get("range_image")
    if not image:
        return []
    beams, sectors = image["beams"], image["azimuth_bins"]
    sections = []
    for quantity, values in image["quantities"].items():
        grid = np.array([np.nan if v is None else v for v in values], dtype=float).reshape(beams, sectors)
        label, cmap = IMAGE_TITLES[quantity]
        finite = grid[np.isfinite(grid)]
        if quantity == "spread":
            norm = matplotlib.colors.TwoSlopeNorm(vcenter=1.0, vmin=min(0.5, finite.min(initial=1.0)),
                                                  vmax=max(1.5, finite.max(initial=1.0)))
        elif quantity == "outliers":
            # Most cells hold none and a few many: a log scale from one in ten thousand, the cells
            # without an outlier grey beneath, so that a handful of outliers still shows where it is.
            ax_zero = np.where(grid == 0.0, 1.0, np.nan)
            grid = np.where(grid > 0.0, np.maximum(grid, 1e-4), np.nan)
            norm = matplotlib.colors.LogNorm(vmin=1e-4, vmax=max(1e-3, finite.max(initial=0.0)))
        else:
            limit = max(1e-3, np.abs(finite).max(initial=0.0))
            norm = matplotlib.colors.Normalize(vmin=-limit, vmax=limit)
        fig, ax = plt.subplots(figsize=(12, 2.2 + beams / 64))
        if quantity == "outliers":
            ax.imshow(ax_zero, origin="upper", aspect="auto", interpolation="nearest",
                      cmap=matplotlib.colors.ListedColormap(["#dddddd"]), extent=(0, 360, beams - 0.5, -0.5))
            label += " (grey: none)"
        shown = ax.imshow(grid, origin="upper", aspect="auto", cmap=cmap, norm=norm, interpolation="nearest",
                          extent=(0, 360, beams - 0.5, -0.5))
        ax.set_xlabel("azimuth (encoder angle), °")
        ax.set_ylabel("beam")
        ax.set_title("%s: %s, beam × azimuth (blank: no pixel meets a surface)" % (quantity, label), fontsize=9)
        fig.colorbar(shown, ax=ax, label=quantity)
        sections.append(("Range image: %s" % quantity, png(fig)))
    return sections


def reliability(report):
    """Measured against predicted detection rate, one point per bin of every single feature."""
    fig, ax = plt.subplots(figsize=(4, 4))
    single = [b for b in report["bins"] if len(b["features"]) == 1 and b["pixels"] >= 30]
    p = [b["detection"]["predicted"] for b in single]
    m = [b["detection"]["measured"] for b in single]
    n = [b["pixels"] for b in single]
    ax.scatter(p, m, s=[max(4, 40 * math.log10(k)) for k in n] if n else 10, alpha=0.5)
    ax.plot([0, 1], [0, 1], color="gray", lw=1)
    ax.set_xlabel("predicted detection rate")
    ax.set_ylabel("measured detection rate")
    ax.set_title("detection reliability (bins)", fontsize=10)
    return png(fig)


def along(report, feature, label):
    """Spread ratio and bias difference along one feature (per beam, per azimuth sector)."""
    bins = sorted(bins_of(report, [feature]), key=lambda b: b["features"][feature][0])
    if not bins:
        return ""
    x = np.array([b["features"][feature][0] for b in bins], dtype=float)
    inliers = np.array([b["inliers"] for b in bins], dtype=float)
    # A bin with few returns (a beam that mostly sees the sky) reads noisy: open grey markers, so a
    # spike there is not taken for a fault.
    few = max(30.0, 0.1 * float(np.median(inliers)))
    thin = inliers < few
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 4), sharex=True)
    for ax, values in ((top, np.array([b["spread_ratio"] for b in bins])),
                       (bottom, np.array([1000 * (b["bias_m"]["measured"] - b["bias_m"]["predicted"]) for b in bins]))):
        ax.plot(x, values, color="#4477aa", lw=1)
        ax.plot(x[~thin], values[~thin], ".", color="#4477aa")
        if thin.any():
            ax.plot(x[thin], values[thin], "o", mfc="none", color="#999999", ms=4,
                    label="fewer than %d returns" % few)
    top.axhline(1.0, color="gray", lw=1)
    top.set_ylabel("spread ratio")
    bottom.axhline(0.0, color="gray", lw=1)
    bottom.set_ylabel("bias misfit, mm")
    bottom.set_xlabel(label)
    if thin.any():
        top.legend(fontsize=7)
    top.set_title("misfit per %s%s" % (label, " (%d of %d with few returns: open grey)" % (thin.sum(), len(bins))
                                        if thin.any() else ""), fontsize=10)
    return png(fig)


def pit(report):
    histogram = report["summary"]["pit_histogram"]
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.bar([(k + 0.5) / len(histogram) for k in range(len(histogram))], histogram, width=1 / len(histogram))
    ax.axhline(1 / len(histogram), color="#cc3311")
    ax.set_xlabel("PIT")
    ax.set_ylabel("fraction of returns")
    ax.set_title("PIT (flat if the model is right; p = %.3g)" % report["summary"]["pit_uniformity_p"], fontsize=10)
    return png(fig)


def failing_table(runs, limit=25):
    rows = "".join(
        "<tr><td>%d</td><td>%s</td><td>%s</td><td>%s</td></tr>"
        % (i + 1, html.escape(f["quantity"]), html.escape(f["sentence"]),
           "%.2g" % f["p_value"] if f["p_value"] > 0 else "&lt; 1e-300")
        for i, f in enumerate(runs[:limit]))
    return ("<table class=\"failing\"><tr><th>#</th><th>quantity</th><th>where and how</th>"
            "<th>p (corrected)</th></tr>%s</table>" % rows) if rows else ""


def waterfall(report):
    """The error across the compared profiles (compare --profile A --profile B ...), same pixels: the
    NLL above the best profile's (so the best is 0, and no bar reads as better than the truth), and
    each profile's own failing regions."""
    steps = report.get("waterfall")
    if not steps:
        return ""
    names = [w["profile"] for w in steps]
    excess = [(w["nll_per_pixel"] - w["nll_expected"]) / w["nll_se"] if w["nll_se"] > 0 else 0 for w in steps]
    best = min(w["nll_per_pixel"] for w in steps)
    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(12, 3))
    left.bar(names, [w["nll_per_pixel"] - best for w in steps], color="#4477aa")
    left.axhline(0, color="gray", lw=1)
    left.set_ylabel("NLL above the best profile,\nnats per pixel")
    middle.bar(names, [1000 * w["bias_rms_m"] for w in steps], color="#ee7733")
    middle.set_ylabel("bias RMS over bins, mm")
    right.bar(names, [w["failing_regions"] for w in steps], color="#cc3311")
    right.set_ylabel("failing regions")
    for ax in (left, middle, right):
        ax.tick_params(axis="x", rotation=30, labelsize=8)
    fig.suptitle("the error as the profile improves", fontsize=10)
    fig.subplots_adjust(wspace=0.45)
    rows = "".join("<tr><td>%s</td><td>%.4f</td><td>%+.4f</td><td>%+.1f</td><td>%.1f mm</td><td>%.2f</td>"
                   "<td>%.4f</td><td>%d</td></tr>"
                   % (html.escape(w["profile"]), w["nll_per_pixel"], w["nll_per_pixel"] - best, e,
                      1000 * w["bias_rms_m"], w["spread_ratio_median"], w["detection_log_loss"], w["failing_regions"])
                   for w, e in zip(steps, excess))
    notes = "".join('<p class="waterfall-note">%s</p>' % html.escape(w["note"]) for w in steps if w.get("note"))
    tables = notes + "".join(
        '<h3 class="profile-failing">%s: %d failing regions</h3>%s'
        % (html.escape(w["profile"]), w["failing_regions"],
           failing_table(w.get("failing_runs", []), 10) or "<p>No region fails.</p>")
        for w in steps)
    return ("<table><tr><th>profile</th><th>NLL/pixel</th><th>above the best</th><th>excess over its own "
            "expectation (SE)</th><th>bias RMS</th><th>median spread ratio</th><th>detection log-loss</th>"
            "<th>failing</th></tr>%s</table>%s%s" % (rows, png(fig), tables))


def number(value):
    return "%.4g" % value


def fitted_value(name, p):
    """"divergence_rad = 0.00192 [0.00191, 0.00193] (robust [0.00185, 0.00199])": the curvature's
    interval, and the sandwich's where the diagnosis computed one."""
    text = "%s = %s [%s, %s]" % (html.escape(name), number(p["value"]), number(p["ci95"][0]), number(p["ci95"][1]))
    robust = p.get("ci95_robust")
    if robust and robust[0] is not None and robust[1] is not None:
        text += " (robust [%s, %s])" % (number(robust[0]), number(robust[1]))
    if p.get("bound"):
        text += ' <b class="bound">(%s: the data does not fix it)</b>' % html.escape(p["bound"])
    return text


def indexed(name):
    """("offsets_m", 104) for "offsets_m/104"; (name, None) for a plain parameter."""
    head, _, tail = name.rpartition("/")
    return (head, int(tail)) if head and tail.isdigit() else (name, None)


def parameters_cell(params, limit=8):
    """A fitted effect's values: all of them where there are few; where there are many (a beam
    offset each), how many, the largest few, and a plot by index. report.json keeps every one."""
    if len(params) <= limit:
        return "<br>".join(fitted_value(name, p) for name, p in params.items())
    groups = {}
    for name, p in params.items():
        head, index = indexed(name)
        groups.setdefault(head, []).append((index if index is not None else -1, name, p))
    parts = []
    for head, items in groups.items():
        items.sort()
        largest = sorted(items, key=lambda item: -abs(item[2]["value"]))[:5]
        parts.append("%d parameters %s (by index; all in report.json); the largest: %s"
                     % (len(items), html.escape(head), "; ".join(fitted_value(name, p) for _, name, p in largest)))
        if len(items) > limit:
            fig, ax = plt.subplots(figsize=(6, 2))
            index = [i for i, _, _ in items]
            value = np.array([p["value"] for _, _, p in items])
            lo = np.array([p["ci95"][0] if p["ci95"][0] is not None else p["value"] for _, _, p in items])
            hi = np.array([p["ci95"][1] if p["ci95"][1] is not None else p["value"] for _, _, p in items])
            ax.errorbar(index, value, yerr=[value - lo, hi - value], fmt=".", ms=3, lw=0.8, color="#4477aa")
            ax.axhline(0.0, color="gray", lw=1)
            ax.set_xlabel("index (%s/N)" % head)
            ax.set_ylabel(head, fontsize=8)
            ax.set_title("%s by index, 95 %% intervals" % head, fontsize=9)
            parts.append(png(fig))
    return "<br>".join(parts)


def diagnosis_section(report):
    """What --diagnose found, as the terminal prints it: the effects it selected with their values and
    95 % intervals, replacements and refits, what stays unexplained, and the command that applies it."""
    d = report.get("diagnosis")
    if d is None:
        return ""
    parts = ["<p>verdict of the search: <b>%s</b> (fits on %d pixels)</p>" % (html.escape(d["verdict"]), d["pixels"])]
    rows = "".join(
        "<tr><td>%s (%s)</td><td>%+.1f</td><td>%s</td></tr>"
        % (html.escape(c["effect"]), html.escape(c["catalogue"]), c["delta_bic"],
           parameters_cell(c["params"]))
        for c in d["selected"])
    if rows:
        parts.append("<table class=\"selected\"><tr><th>selected effect</th><th>delta BIC, given the effects "
                     "selected before it</th>"
                     "<th>fitted value [95 %% interval] (robust interval)</th></tr>%s</table>" % rows)
    else:
        parts.append("<p>No library effect is selected.</p>")
    ranked = "".join("<tr><td>%s (%s)</td><td>%+.1f</td></tr>" % (html.escape(c["effect"]), html.escape(c["catalogue"]),
                                                                 c["delta_bic"]) for c in d.get("ranked", [])[:5])
    if ranked:
        parts.append("<table class=\"ranked\"><tr><th>candidate</th><th>delta BIC, fitted alone against the "
                     "profile (as the terminal ranks them)</th></tr>%s</table>" % ranked)
    if d.get("intervals_caveat"):
        parts.append("<p class=\"intervals-caveat\"><b>About the intervals:</b> %s</p>"
                     % html.escape(d["intervals_caveat"]))
    items = ["replace: " + r["sentence"] for r in d["replace"]]
    for m in d["parameter_misfit"]:
        moved = sorted(m["params"].items(), key=lambda item: -abs(item[1]["value"] - m["old"].get(item[0], 0.0)))
        changes = ", ".join("%s %s → %s" % (name, number(m["old"].get(name, 0.0)), number(p["value"]))
                            for name, p in moved[:8])
        if len(moved) > 8:
            changes += " (the 8 that moved most of %d; all in report.json)" % len(moved)
        items.append("refitted %s (%s channel, delta BIC %+.1f): %s" % (m["effect"], m["channel"], m["delta_bic"], changes))
    items += [s["sentence"] for s in d["shared"]] + [n["sentence"] for n in d["not_selected"]]
    items += ["unexplained: " + u["sentence"] for u in d["unexplained"]]
    if d.get("remaining", {}).get("note"):
        items.append(d["remaining"]["note"])
    if not d["unexplained"]:
        items.append("Nothing stays unexplained: with the selected effects no quantity fails any more.")
    parts.append("<ul>%s</ul>" % "".join("<li>%s</li>" % html.escape(i) for i in items))
    if report.get("next_command"):
        parts.append("<p>To apply it:</p><pre class=\"next-command\">%s</pre>" % html.escape(report["next_command"]))
    return "".join(parts)


def page(report):
    s = report["summary"]
    inputs = report.get("inputs", {})
    excess = (s["nll_per_pixel"] - s["nll_expected"]) / s["nll_se"] if s["nll_se"] > 0 else 0.0
    failing = (failing_table(report.get("failing_runs", report["failing"]))
               or "<p><b>No region fails</b> at alpha %g (%d tests).</p>" % (s["alpha"], s["tests"]))
    sections = [
        ("Diagnosis", diagnosis_section(report)),
        ("The error across profiles", waterfall(report)),
        ("Where the model fails", failing),
        ("Spread misfit: range × incidence", heat_map(report, "range", "incidence", "spread", "the spread against the model's")),
        ("Bias misfit: range × incidence", heat_map(report, "range", "incidence", "bias", "the bias against the model's")),
        ("Spread misfit: range × reflectivity",
         heat_map(report, "range", "reflectivity", "spread", "the spread against the model's")),
        ("Bias misfit: range × reflectivity", heat_map(report, "range", "reflectivity", "bias", "the bias against the model's")),
    ] + range_images(report) + [
        ("Range residuals per range band", residual_histograms(report)),
        ("Detection", reliability(report)),
        ("PIT", pit(report)),
        ("Per beam", along(report, "beam", "beam")),
        ("Per azimuth", along(report, "azimuth", "azimuth (°)")),
    ]
    body = "".join("<h2>%s</h2>%s" % (title, content) for title, content in sections if content)
    return """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>lidartwin compare: %s</title>
<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;font-size:13px;text-align:left}
.summary td:first-child{font-weight:bold}.verdict{font-size:17px}
pre{background:#f4f4f4;padding:6px;white-space:pre-wrap}</style></head><body>
<h1>lidartwin compare</h1>
<p class="verdict"><b>%s</b></p>
<p>%s compared with profile <b>%s</b></p>
<table class="summary">
<tr><td>frames, pixels, returns</td><td>%d, %d, %d</td></tr>
<tr><td>NLL per pixel</td><td>%.4f (expected %.4f ± %.4f if the model were true: %+.1f standard errors)</td></tr>
<tr><td>detection</td><td>%.2f %% measured, %.2f %% predicted</td></tr>
<tr><td>range z</td><td>mean %+.3f, std %.3f</td></tr>
<tr><td>failing regions</td><td>%d (alpha %g, %d tests, Bonferroni)</td></tr>
</table>%s
<script>
// How many plots the browser decoded: tests/cli_compare_test.cpp reads these from the DOM.
window.addEventListener("load", () => {
  const images = Array.from(document.images);
  document.body.dataset.plotsTotal = images.length;
  document.body.dataset.plotsRendered = images.filter((i) => i.complete && i.naturalWidth > 0).length;
});
</script></body></html>
""" % (html.escape(str(inputs.get("capture", ""))), html.escape(report.get("verdict_sentence", "")), html.escape(str(inputs.get("capture", "the capture"))),
       html.escape(str(inputs.get("profile", "?"))), s["frames"], s["pixels"], s["returns"], s["nll_per_pixel"],
       s["nll_expected"], s["nll_se"], excess, 100 * s["detection"]["measured"], 100 * s["detection"]["predicted"],
       s["z"]["mean"], s["z"]["std"], len(report["failing"]), s["alpha"], s["tests"], body)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    directory = Path(sys.argv[1])
    report = json.loads((directory / "report.json").read_text())
    # Whole or not at all: under a temporary name, then renamed (a full disk leaves no torn page).
    partial = directory / ("report.html.partial.%d" % os.getpid())
    try:
        partial.write_text(page(report), encoding="utf-8")
        os.replace(partial, directory / "report.html")
    finally:
        if partial.exists():
            partial.unlink()


if __name__ == "__main__":
    main()
