# bake_phases.py PERF_DATA BAKE_JSON [BUCKET_S]: a bake's CPU by phase and its wall on two
# idle cores, from `perf record -F 250 -- wrt-bake ... --json > BAKE_JSON` (docs/bench.md,
# "Session 10: the bake's one-thread stretches"). The samples are cut at the --json
# phases' edges (load, dto, balance, series, write, in that order from the first sample).
# Per phase: its CPU (samples / 250), the calling thread's, and the projected wall: each
# BUCKET_S of the run (0.5 s by default) counted as the larger of its busiest thread's CPU
# and half its CPU, i.e. what two idle cores would take for that slice when no thread
# waits for another; "parallel" is CPU / projected (2 at best). Needs perf on the PATH.
import collections, json, subprocess, sys

HZ = 250.0


def samples(data):
    out = subprocess.run(["perf", "script", "-i", data, "-F", "comm,tid,time,ip,sym"], capture_output=True,
                         text=True, check=True).stdout
    got = []
    for line in out.splitlines():
        w = line.split()
        if len(w) >= 3 and w[1].isdigit() and w[2].endswith(":"):
            got.append((w[0], int(w[1]), float(w[2][:-1])))
    return [s for s in got if s[0].startswith("wrt-bake")]


def main():
    data, js = sys.argv[1], sys.argv[2]
    bucket = float(sys.argv[3]) if len(sys.argv) > 3 else 0.5
    sec = json.load(open(js))["seconds"]
    phases, at = [], 0.0
    for name in ("load", "dto", "balance", "series", "write"):
        phases.append((name, at, at + sec[name]))
        at += sec[name]
    s = samples(data)
    if not s:
        sys.exit("no wrt-bake samples in " + data)
    t0, main_tid = s[0][2], s[0][1]
    slices = collections.defaultdict(collections.Counter)
    for _, tid, t in s:
        slices[int((t - t0) / bucket)][tid] += 1
    cpu, mine, proj = collections.Counter(), collections.Counter(), collections.Counter()
    for k, c in slices.items():
        mid = (k + 0.5) * bucket
        ph = next((n for n, a, b in phases if a <= mid < b), "after")
        tot = sum(c.values()) / HZ
        cpu[ph] += tot
        mine[ph] += c[main_tid] / HZ
        proj[ph] += max(max(c.values()) / HZ, tot / 2)
    print("phase    wall_s  cpu_s  main_s  projected_s  parallel")
    for name, a, b in phases + [("after", at, at)]:
        par = cpu[name] / proj[name] if proj[name] else 0
        print(f"{name:8s} {b - a:6.2f} {cpu[name]:6.2f} {mine[name]:7.2f} {proj[name]:12.2f} {par:9.2f}")
    total_cpu, total_proj = sum(cpu.values()), sum(proj.values())
    print(f"all             {total_cpu:6.2f} {sum(mine.values()):7.2f} {total_proj:12.2f} {total_cpu / total_proj:9.2f}")


if __name__ == "__main__":
    main()
