#!/usr/bin/env python3
"""mpi_model.py LOG [--tag TAG] [--at N]: docs/mpi.md's model ("A model for 16 to 256 ranks") from
wrt-bake-mpi's report lines (WRT_MPI_REPORT=1). LOG holds, for each run, a line
"TAG SCENE npN rc=R wall=W load=L" and then that run's report lines (one a rank). The
1-rank runs may carry any tag (one rank is the same code in every version); the 4-rank
runs are those tagged TAG (default fin). SCENE is atrium05 or atrium1: the generator's
atrium at detail 0.5 and 1 (1,060 and 2,704 elements). Prints the inputs' table and the
model's table in Markdown; with --at N, also the model's figures a rank at 1, 2 and 4 ranks
for an atrium of N elements (to check it against a run it was not fitted to)."""
import math
import re
import sys

REPORT = re.compile(r"rank (\d+) of (\d+): cpu dto ([\d.]+) s \(cluster links ([\d.]+), assembly ([\d.]+)\) "
                    r"series ([\d.]+) s; peak rss ([\d.]+) MB \(to the series ([\d.]+) MB\); sent dto (\d+) "
                    r"series (\d+) counters (\d+) bytes; received dto (\d+) series (\d+) counters (\d+) bytes")
HEAD = re.compile(r"(\w+) (\S+) np(\d+) rc=(\d+)")
ELEMENTS = {"atrium05": 1060, "atrium1": 2704}
TRI_PER_ELEMENT = 4508 / 2704  # the atrium at detail 1
BANDWIDTH = 1e9               # bytes a second a rank


def read(path):
    runs, cur = {}, None
    for line in open(path):
        m = HEAD.match(line)
        if m:
            cur = (m.group(1), m.group(2), int(m.group(3)))
            runs[cur] = []
            continue
        m = REPORT.search(line)
        if m and cur:
            g = m.groups()
            runs[cur].append({"dto": float(g[2]), "series": float(g[5]), "peak": float(g[6]),
                              "peak_dto": float(g[7]), "rdto": int(g[11]) / 1e6, "rser": int(g[12]) / 1e6})
    return runs


def largest(runs, scene, n, tag, key):
    for (t, s, k), ranks in runs.items():
        if s == scene and k == n and (n == 1 or t == tag) and ranks:
            return max(r[key] for r in ranks)
    sys.exit(f"mpi_model: no {n}-rank run of {scene} (tag {tag}) in the log")


def main():
    args = sys.argv[1:]
    tag = "fin"
    if "--tag" in args:
        i = args.index("--tag")
        tag = args[i + 1]
        del args[i:i + 2]
    at_n = None
    if "--at" in args:
        i = args.index("--at")
        at_n = int(args[i + 1])
        del args[i:i + 2]
    if len(args) != 1:
        sys.exit(__doc__)
    runs = read(args[0])
    fit = {}  # (scene, key) -> (replicated or undivided, divided), or the bytes B
    for scene in ELEMENTS:
        for key in ("dto", "series", "peak", "peak_dto"):
            c1, c4 = largest(runs, scene, 1, tag, key), largest(runs, scene, 4, tag, key)
            d = 4 / 3 * (c1 - c4)
            fit[scene, key] = (c1 - d, d)
        for key in ("rdto", "rser"):
            fit[scene, key] = 4 / 3 * largest(runs, scene, 4, tag, key)
    ratio = math.log(ELEMENTS["atrium1"] / ELEMENTS["atrium05"])

    def expo(a, b):
        return math.log(b / a) / ratio if a > 0 and b > 0 else 0.0

    ex = {}
    print("| input (atrium, detail 1) | value (detail 0.5) | exponent e |\n|---|---|---|")
    names = {"dto": ("DTO phase CPU", "s", "undivided R", "divided D"),
             "series": ("series CPU", "s", "undivided R", "divided D"),
             "peak": ("peak memory", "MB", "replicated M_rep", "divided M_div"),
             "peak_dto": ("the DTO phase's own peak", "MB", "replicated M_rep", "divided M_div")}
    for key, (name, unit, rname, dname) in names.items():
        (r1, d1), (r0, d0) = fit["atrium1", key], fit["atrium05", key]
        ex[key] = (expo(r0, r1), expo(d0, d1))
        print(f"| {name}, {dname} | {d1:.2f} {unit} ({d0:.2f} {unit}) | {ex[key][1]:.2f} |")
        print(f"| {name}, {rname} | {r1:.2f} {unit} ({r0:.2f} {unit}) | {ex[key][0]:.2f} |")
    for key, name in (("rdto", "bytes B, DTO"), ("rser", "bytes B, series")):
        b1, b0 = fit["atrium1", key], fit["atrium05", key]
        ex[key] = expo(b0, b1)
        print(f"| {name} | {b1:.1f} MB ({b0:.1f} MB) | {ex[key]:.2f} |")
    if at_n:
        s = at_n / ELEMENTS["atrium1"]

        def pred(key, n):
            r, d = fit["atrium1", key]
            return (r * s ** ex[key][0] if r > 0 else 0.0) + (d * s ** ex[key][1] if d > 0 else 0.0) / n

        print(f"\n| {at_n} elements | ranks | DTO phase CPU s / rank | series CPU s / rank | peak MB / rank | "
              "the DTO phase's peak MB / rank |\n|---|---|---|---|---|---|")
        for n in (1, 2, 4):
            print(f"| | {n} | {pred('dto', n):.1f} | {pred('series', n):.1f} | {pred('peak', n):.0f} | "
                  f"{pred('peak_dto', n):.0f} |")
    print("\n| scene | ranks | time / rank | speed-up | DTO phase / rank (its speed-up) | memory / rank | received / rank |")
    print("|---|---|---|---|---|---|---|")
    for label, tri in (("10^5 triangles", 1e5), ("10^6 triangles", 1e6)):
        s = tri / TRI_PER_ELEMENT / ELEMENTS["atrium1"]

        def at(key, i):
            v = fit["atrium1", key][i]
            return v * s ** ex[key][i] if v > 0 else 0.0

        rd, dd, rs, ds, mr, md = at("dto", 0), at("dto", 1), at("series", 0), at("series", 1), at("peak", 0), at("peak", 1)
        bd = fit["atrium1", "rdto"] * 1e6 * s ** ex["rdto"]
        bs = fit["atrium1", "rser"] * 1e6 * s ** ex["rser"]
        one = rd + dd + rs + ds
        for n in (1, 16, 64, 256):
            td = rd + dd / n + bd * (1 - 1 / n) / BANDWIDTH
            t = td + rs + ds / n + bs * (1 - 1 / n) / BANDWIDTH
            got = (bd + bs) * (1 - 1 / n)
            got_s = "0" if n == 1 else f"{got / 1e12:.1f} TB" if got >= 1e12 else f"{got / 1e9:.0f} GB"
            t_s = f"{t:,.0f} s" if t < 1e5 else f"{t:.2g} s"
            print(f"| {label if n == 1 else ''} | {n} | {t_s} | {one / t:.0f} | {td:,.0f} s ({(rd + dd) / td:.1f}) | "
                  f"{(mr + md / n) / 1024:.1f} GB | {got_s} |")


if __name__ == "__main__":
    main()
