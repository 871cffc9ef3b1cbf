#!/usr/bin/env python3
"""scan_fit.py: fits `wrt-bake --scan`'s cost model (precompute/scan.c) to measured bakes.

Reads docs/scan_fit.csv (one measured bake a row: the scene, its elements and visible
fraction as `wrt-bake --scan --json` reports them, the quality, plain or clusters, the
bake's CPU seconds, peak resident MB and .gto bytes) and fits, for the plain bake and
for --clusters separately, each figure y (CPU seconds; peak MB over the process's base;
bytes) as

    y = c * step^(q - 5) * (N / 1000)^(a + k (min(q, 5) - 5)) * (f / 0.3)^g * (x / 0.1)^h

(N the elements, f the visible fraction, x the exchange fraction: the share of element
pairs that face each other, q the quality): the exponents that make the
band of log(measured / model) over the bakes narrowest (a minimax fit, started from least
squares on log y), then c set so that no measured bake lies above its estimate: the
estimate is an upper bound, and the band is how far above a bake it can lie. Prints the constants as scan.c's
initializers and, for every bake, the estimate over the measured figure.

Usage: tools/scan_fit.py [docs/scan_fit.csv] [--markdown] [--no-visible] [--no-exchange]
    --markdown: the residual table as docs/triangles.md shows it
    --no-visible: the elements alone (g = 0, h = 0), to compare
    --no-exchange: without the exchange fraction (h = 0: session 7's model), to compare
No third-party modules (the normal equations are solved here).
"""
import csv
import math
import sys

MB_BASE = 30.0  # scan.c's SCAN_MB_BASE: the process itself
FIGURES = ("cpu_s", "peak_mb", "bytes")
# c is raised over the highest row by a bake's run-to-run spread, so that the bound holds for
# a rerun of a fitted bake too: its CPU and peak vary (the atrium at detail 0.25, --clusters
# -q 1: peak 122.7 to 155.1 MB in four runs), its bytes not, but --scan prints 4 digits
SPREAD = {"cpu_s": 1.1, "peak_mb": 1.1, "bytes": 1.01}


def solve(a, b):
    """Solves the square system a x = b by Gaussian elimination with partial pivoting."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for k in range(n):
        p = max(range(k, n), key=lambda i: abs(m[i][k]))
        if abs(m[p][k]) < 1e-12:
            raise ValueError("singular fit: the rows do not vary in every feature")
        m[k], m[p] = m[p], m[k]
        for i in range(k + 1, n):
            f = m[i][k] / m[k][k]
            for j in range(k, n + 1):
                m[i][j] -= f * m[k][j]
    x = [0.0] * n
    for k in reversed(range(n)):
        x[k] = (m[k][n] - sum(m[k][j] * x[j] for j in range(k + 1, n))) / m[k][k]
    return x


USE_VISIBLE = "--no-visible" not in sys.argv
# the exchange fraction for the plain bake only: it links every pair of elements that face
# each other (its pair list); --clusters links clusters, not element pairs
USE_EXCHANGE = USE_VISIBLE and "--no-exchange" not in sys.argv


def features(r):
    g = math.log(max(r["visible"], 1e-3) / 0.3) if USE_VISIBLE else 0.0
    h = math.log(max(r["exchange"], 1e-4) / 0.1) if USE_EXCHANGE and r["bake"] == "plain" else 0.0
    # the exponent of N moves with the quality (k): with --clusters quality 5's CPU grows as
    # N^0.7 over 5,048 to 22,224 atrium elements where quality 1's grows as N^1.2; the
    # plain bake's too since its quality-1 rows (session 20: without k its band grew from
    # 1.7x to 3.6x); the qualities over 5 take quality 5's exponent (none is fitted there)
    qn = (min(r["quality"], 5) - 5.0) * math.log(r["elements"] / 1000.0)
    return [1.0, r["quality"] - 5.0, math.log(r["elements"] / 1000.0), g, h, qn]


def target(r, fig):
    y = r[fig]
    return y - MB_BASE if fig == "peak_mb" else y


def nelder_mead(f, x0, scale, iters=4000):
    """Minimizes f from x0 (a plain Nelder-Mead simplex; deterministic)."""
    n = len(x0)
    pts = [list(x0)] + [[x0[j] + (scale[j] if j == i else 0) for j in range(n)] for i in range(n)]
    vals = [f(p) for p in pts]
    for _ in range(iters):
        order = sorted(range(n + 1), key=lambda i: vals[i])
        pts = [pts[i] for i in order]
        vals = [vals[i] for i in order]
        if vals[-1] - vals[0] < 1e-12:
            break
        mid = [sum(p[j] for p in pts[:-1]) / n for j in range(n)]
        refl = [mid[j] + (mid[j] - pts[-1][j]) for j in range(n)]
        fr = f(refl)
        if fr < vals[0]:
            exp = [mid[j] + 2 * (mid[j] - pts[-1][j]) for j in range(n)]
            fe = f(exp)
            pts[-1], vals[-1] = (exp, fe) if fe < fr else (refl, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = refl, fr
        else:
            con = [mid[j] + 0.5 * (pts[-1][j] - mid[j]) for j in range(n)]
            fc = f(con)
            if fc < vals[-1]:
                pts[-1], vals[-1] = con, fc
            else:
                pts = [pts[0]] + [[pts[0][j] + 0.5 * (p[j] - pts[0][j]) for j in range(n)] for p in pts[1:]]
                vals = [vals[0]] + [f(p) for p in pts[1:]]
    return pts[0]


def fit(rows, fig):
    """The exponents that make the band of log(measured / model) narrowest (least squares
    on log y first, then the largest residual minimized, a minimax fit: what an upper bound
    within a factor needs); returns (c, step, a, g, h, k) with c raised to bound every row."""
    x = [features(r) for r in rows]
    if not any(xi[5] != 0 for xi in x):  # every row at quality 5 (or N = 1000): no k
        x = [xi[:5] + [0.0] for xi in x]
    y = [math.log(target(r, fig)) for r in rows]
    exch = any(xi[4] != 0 for xi in x)
    n = len(x[0])
    # a small ridge on the visible fraction's exponent keeps it defined when the rows'
    # fractions barely vary (one family of scenes)
    qn = any(xi[5] != 0 for xi in x)
    if not qn:
        n = 5
    ata = [[sum(xi[i] * xi[j] for xi in x) + (1e-3 if i == j and i >= 3 else 0) for j in range(n)] for i in range(n)]
    aty = [sum(xi[i] * yi for xi, yi in zip(x, y)) for i in range(n)]
    b = solve(ata, aty)
    if not qn:
        b = b + [0.0]

    def pred(e, xi):
        return e[0] * xi[1] + e[1] * xi[2] + e[2] * xi[3] + e[3] * xi[4] + (e[4] * xi[5] if len(e) > 4 else 0.0)

    def band(e):  # the spread of the residuals for exponents e = (log step, a, g, h, k)
        res = [yi - pred(e, xi) for xi, yi in zip(x, y)]
        return max(res) - min(res)

    e = b[1:]
    for _ in range(3):  # restarted: the simplex stalls on the band's corners
        if qn:
            e = nelder_mead(band, e, [0.1, 0.1, 0.1 if USE_VISIBLE else 0.0, 0.1 if exch else 0.0, 0.05])
        else:  # four exponents: the plain model's fit as before k
            e = nelder_mead(band, e[:4], [0.1, 0.1, 0.1 if USE_VISIBLE else 0.0, 0.1 if exch else 0.0]) + [0.0]
    if not USE_VISIBLE:
        e[2] = 0.0
    if not exch:
        e[3] = 0.0
    if not qn:
        e[4] = 0.0
    top = max(yi - pred(e, xi) for xi, yi in zip(x, y))
    return (math.exp(top) * SPREAD[fig], math.exp(e[0]), e[1], e[2], e[3], e[4])


def estimate(m, r, fig):
    c, step, a, g, h, k = m
    e = c * step ** (r["quality"] - 5) * (r["elements"] / 1000.0) ** (a + k * (min(r["quality"], 5) - 5)) * \
        (max(r["visible"], 1e-3) / 0.3) ** g
    if h:
        e *= (max(r["exchange"], 1e-4) / 0.1) ** h
    return e + MB_BASE if fig == "peak_mb" else e


def load(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(line for line in f if not line.startswith("#")):
            for k in ("elements", "quality"):
                r[k] = int(r[k])
            for k in ("visible", "exchange") + FIGURES:
                r[k] = float(r[k])
            rows.append(r)
    return rows


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    md = "--markdown" in sys.argv
    rows = load(args[0] if args else "docs/scan_fit.csv")
    for kind in ("plain", "clusters"):
        sel = [r for r in rows if r["bake"] == kind]
        if len(sel) < 5:
            print("%s: %d bakes, too few to fit" % (kind, len(sel)), file=sys.stderr)
            continue
        models = {fig: fit(sel, fig) for fig in FIGURES}
        print("/* %s: %d bakes; visible fractions from %.4f, exchange fractions %.4f to %.4f */" % (
            kind, len(sel), min(r["visible"] for r in sel), min(r["exchange"] for r in sel),
            max(r["exchange"] for r in sel)))
        for fig in FIGURES:
            c, step, a, g, h, k = models[fig]
            print("    {%.4g, %.4f, %.4f, %.4f, %.4f, %.4f}, /* %s */" % (c, step, a, g, h, k, fig))
        if md:
            print("\n| scene | elements | visible | exchange | quality | bake | CPU s | est. / CPU | peak MB | est. / peak | MB | est. / MB |")
            print("|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|")
        worst = {fig: (9e9, 0.0) for fig in FIGURES}
        for r in sel:
            ratio = {fig: estimate(models[fig], r, fig) / r[fig] for fig in FIGURES}
            for fig in FIGURES:
                lo, hi = worst[fig]
                worst[fig] = (min(lo, ratio[fig]), max(hi, ratio[fig]))
            if md:
                print("| %s | %d | %.3f | %.4f | %d | %s | %.1f | %.2f | %.0f | %.2f | %.1f | %.2f |" % (
                    r["scene"], r["elements"], r["visible"], r["exchange"], r["quality"], kind, r["cpu_s"], ratio["cpu_s"],
                    r["peak_mb"], ratio["peak_mb"], r["bytes"] / 1e6, ratio["bytes"]))
        print("/* estimate / measured: " + ", ".join(
            "%s %.2f-%.2f" % (fig, worst[fig][0], worst[fig][1]) for fig in FIGURES) + " */\n")


if __name__ == "__main__":
    main()
