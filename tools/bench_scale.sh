#!/usr/bin/env bash
# bench_scale.sh: issue 22's scale benchmark. Bakes the atrium (wrt-scenegen atrium) at
# several --detail values, the N x N mazes and, for issue 21's cost against triangle count,
# cornell-shapes at --detail values (SHAPES) at one quality, and records per scene: the
# elements (wrt-bake --scan), the bake's CPU seconds (user + system) and wall seconds
# (/usr/bin/time), its peak resident memory (--json's memory_mb.peak_rss) and largest
# estimate, the file's size and the light change (wrt-play --headless --bench: median ms
# of projection + multiply + BRDF + synthesis; FRAMES=0 skips it). A scene whose --scan
# estimate (at QUALITY, with BAKE_OPTS: --clusters has its own model) passes the
# memory cap is skipped and recorded so; every bake also runs under --max-memory CAP, and
# one that the bake refuses is recorded as refused. Rows are appended to DIR/scale.csv
# (one LABEL per build or option set), then tools/bench_scale_plot.py fits the slopes
# (least squares on log-log) and draws DIR/scale.png (gnuplot). docs/bench.md explains.
# Usage: tools/bench_scale.sh [BUILD] [DIR]     (defaults: build, bench-scale)
#   env DETAILS="0.25 0.5 0.7" MAZES="4 6 8 12" SHAPES="" (e.g. "2 3.5 6.25": about 1k,
#       3k and 10k triangles) QUALITY=5 CAP_MB=6000 FRAMES=20
#       BAKE_OPTS="--clusters" (passed to wrt-bake) LABEL=name (default: the git commit)
#       KEEP=1 keeps the .gto files
set -euo pipefail
build=${1:-build}
dir=${2:-bench-scale}
cd "$(dirname "$0")/.."
details=${DETAILS-"0.25 0.5 0.7"}
mazes=${MAZES-"4 6 8 12"}
shapes=${SHAPES-}
quality=${QUALITY:-5}
cap=${CAP_MB:-6000}
frames=${FRAMES:-20}
bake_opts=${BAKE_OPTS:-}
label=${LABEL:-$(git rev-parse --short HEAD 2>/dev/null || echo build)}
for p in wrt-bake wrt-play wrt-scenegen; do
    [ -x "$build/$p" ] || { echo "bench_scale: $build/$p is missing (make all)" >&2; exit 1; }
done
[ -x /usr/bin/time ] || { echo "bench_scale: /usr/bin/time is missing (apt-get install time)" >&2; exit 1; }
mkdir -p "$dir"
csv=$dir/scale.csv
[ -s "$csv" ] || echo "label,scene,param,elements,cpu_s,wall_s,peak_mb,estimate_mb,scan_estimate_mb,file_mb,light_change_ms,status" >"$csv"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
num() { tr -d '\n ' <"$2" | grep -o "\"$1\":[0-9.e+-]*" | head -n 1 | cut -d: -f2; }

one() {  # one SCENE PARAM scenegen-options...
    local scene=$1 param=$2; shift 2
    local g=$tmp/$scene-$param.gltf o=$tmp/$scene-$param.gto
    "$build/wrt-scenegen" "$scene" "$@" -o "$g" >/dev/null
    # shellcheck disable=SC2086
    "$build/wrt-bake" --scan "$g" --json --quality "$quality" $bake_opts >"$tmp/scan.json"
    local n est
    n=$(num quads "$tmp/scan.json")
    est=$(tr -d '\n ' <"$tmp/scan.json" | grep -o '"estimate":{[^}]*}' | grep -o '"memory_mb":[0-9.e+-]*' | cut -d: -f2)
    if awk -v e="$est" -v c="$cap" 'BEGIN {exit !(e > c)}'; then
        echo "$label,$scene,$param,$n,,,,,$est,,,skipped: estimate over ${cap} MB" >>"$csv"
        echo "bench_scale: $scene $param: $n elements, skipped (--scan estimates $est MB > $cap MB)" >&2
        return
    fi
    echo "bench_scale: $scene $param: $n elements, baking ($(date -u +%H:%M:%S))" >&2
    local rc=0
    # shellcheck disable=SC2086
    /usr/bin/time -f '%U %S %e %M' -o "$tmp/time" "$build/wrt-bake" "$g" -o "$o" --quality "$quality" \
        --max-memory "$cap" --json --quiet $bake_opts >"$tmp/bake.json" 2>"$tmp/bake.err" || rc=$?
    local cpu wall
    cpu=$(tail -n 1 "$tmp/time" | awk '{printf "%.2f", $1 + $2}')
    wall=$(tail -n 1 "$tmp/time" | awk '{printf "%.2f", $3}')
    if [ "$rc" -ne 0 ]; then
        local why="failed (exit $rc)"
        [ "$rc" -eq 7 ] && why="refused by --max-memory"
        echo "$label,$scene,$param,$n,$cpu,$wall,,,$est,,,$why" >>"$csv"
        echo "bench_scale: $scene $param: $why: $(head -c 300 "$tmp/bake.err")" >&2
        return
    fi
    local peak bestim bytes lc
    peak=$(tr -d '\n ' <"$tmp/bake.json" | grep -o '"memory_mb":{[^}]*}' | grep -o '"peak_rss":[0-9.e+-]*' | cut -d: -f2)
    bestim=$(tr -d '\n ' <"$tmp/bake.json" | grep -o '"memory_mb":{[^}]*}' | grep -o '"estimated":[0-9.e+-]*' | cut -d: -f2)
    bytes=$(num bytes "$tmp/bake.json")
    lc=
    if [ "$frames" -eq 0 ]; then :
    elif "$build/wrt-play" "$o" --headless --msaa 1 --bench "$frames" >"$tmp/play.json" 2>"$tmp/play.err"; then
        lc=$(tr -d '\n ' <"$tmp/play.json" | grep -o '"median_ms":{[^}]*}' | tr ',{}' '\n\n\n' |
             awk -F: '$1 ~ /projection|multiply|brdf|synthesis/ {s += $2} END {printf "%.3f", s}')
    else
        echo "bench_scale: $scene $param: wrt-play --bench failed: $(head -c 200 "$tmp/play.err")" >&2
    fi
    echo "$label,$scene,$param,$n,$cpu,$wall,$peak,$bestim,$est,$(awk -v b="$bytes" 'BEGIN {printf "%.2f", b / 1048576}'),$lc,ok" >>"$csv"
    echo "bench_scale: $scene $param: $n elements, $cpu s CPU, $wall s wall, peak $peak MB, $bytes bytes, light change $lc ms" >&2
    if [ -n "${KEEP:-}" ]; then cp "$o" "$dir/$scene-$param.gto"; fi
    rm -f "$o"
}

for n in $mazes; do one maze "$n" --cells "$n"; done
for d in $details; do one atrium "$d" --detail "$d"; done
for d in $shapes; do one cornell-shapes "$d" --detail "$d"; done
python3 tools/bench_scale_plot.py "$csv" "$dir/scale.png"
