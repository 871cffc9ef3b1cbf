#!/usr/bin/env python3
"""bench_scale_plot.py CSV PNG: the scale benchmark's fits and plot (tools/bench_scale.sh).

Reads the rows tools/bench_scale.sh wrote, fits y = a * elements^b by least squares on
log-log for the bake's CPU seconds, file MB and peak MB, per label and scene family
(atrium, maze) and per label over all scenes, prints a markdown table of the runs and one
of the slopes, and draws the three quantities against the elements on log-log axes with
the lines fitted per scene family (gnuplot, pngcairo). Python's standard library only."""
import csv
import math
import os
import subprocess
import sys
import tempfile

QUANT = [("cpu_s", "bake CPU (s)"), ("file_mb", "file (MB)"), ("peak_mb", "peak memory (MB)")]


def fit(pts):
    """Least squares of log y on log x: returns (a, b, n) for y = a x^b, or None."""
    pts = [(math.log(x), math.log(y)) for x, y in pts if x > 0 and y > 0]
    n = len(pts)
    if n < 2:
        return None
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    if sxx <= 0:
        return None
    b = sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx
    return math.exp(my - b * mx), b, n


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: bench_scale_plot.py CSV PNG")
    rows = list(csv.DictReader(open(sys.argv[1])))
    ok = [r for r in rows if r["status"] == "ok"]
    print("| label | scene | param | elements | bake CPU (s) | wall (s) | peak (MB) | estimate (MB) | file (MB) | light change (ms) | status |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for r in rows:
        print("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            r["label"], r["scene"], r["param"], r["elements"], r["cpu_s"], r["wall_s"], r["peak_mb"],
            r["estimate_mb"], r["file_mb"], r["light_change_ms"], r["status"]))
    groups = {}
    for r in ok:
        for key in ((r["label"], r["scene"]), (r["label"], "all")):
            groups.setdefault(key, []).append(r)
    print()
    print("| label | scenes | runs | CPU slope | file slope | peak slope |")
    print("|---|---|---:|---:|---:|---:|")
    fits = {}
    for key in sorted(groups):
        g = groups[key]
        f = [fit([(float(r["elements"]), float(r[q])) for r in g if r[q]]) for q, _ in QUANT]
        fits[key] = f
        print("| %s | %s | %d | %s |" % (key[0], key[1], len(g), " | ".join(
            "%.2f" % x[1] if x else "-" for x in f)))
    # the plot: one panel per quantity, points and fitted lines per (label, scene)
    series = sorted({(r["label"], r["scene"]) for r in ok})
    labels = sorted({r["label"] for r in ok})
    fd, data = tempfile.mkstemp(suffix=".dat")
    with os.fdopen(fd, "w") as f:
        for lab, sc in series:
            f.write("# %s %s\n" % (lab, sc))
            for r in sorted((r for r in ok if (r["label"], r["scene"]) == (lab, sc)), key=lambda r: float(r["elements"])):
                f.write("%s %s %s %s\n" % (r["elements"], r["cpu_s"] or "NaN", r["file_mb"] or "NaN", r["peak_mb"] or "NaN"))
            f.write("\n\n")
    gp = ['set terminal pngcairo size 1500,500 font "sans,10"', 'set output "%s"' % sys.argv[2],
          "set logscale xy", "set grid", "set key top left", "set multiplot layout 1,3"]
    for col, (q, title) in enumerate(QUANT):
        gp.append('set title "%s against elements (log-log)"' % title)
        gp.append('set xlabel "elements"')
        plots = []
        for i, (lab, sc) in enumerate(series):
            plots.append('"%s" index %d using 1:%d with points pt %d ps 1.5 title "%s %s"' % (data, i, col + 2, 5 + 2 * (i % 5), lab, sc))
        for lab, sc in series:  # a line per scene family (families differ in cost per element)
            f = fits.get((lab, sc), [None] * 3)[col]
            if f:
                plots.append("%.6g * x**%.6g with lines lw 2 title \"%s %s fit: slope %.2f\"" % (f[0], f[1], lab, sc, f[1]))
        gp.append("plot " + ", ".join(plots) if plots else "plot 1 notitle")
    gp.append("unset multiplot")
    try:
        subprocess.run(["gnuplot"], input="\n".join(gp) + "\n", text=True, check=True)
    except (OSError, subprocess.CalledProcessError) as e:
        sys.exit("bench_scale_plot: gnuplot failed (%s); the table above stands" % e)
    finally:
        os.unlink(data)


if __name__ == "__main__":
    main()
