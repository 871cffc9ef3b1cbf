#!/usr/bin/env bash
# kill.sh: a maze bake killed at evenly spaced moments (SIGKILL and SIGINT, with and
# without --max-error) leaves the older output byte for byte as it was and no other file
# in its folder; SIGINT ends it with the documented exit code 4 (or by the signal, 130,
# if it lands before main() runs, while the shared libraries load). The moments are
# fractions (k + 0.5) / N of the measured length of an uninterrupted bake, so they fall
# in the scene load, the operator's computation, the accuracy check and the write.
# N is 3 in `make test` (12 kills), 10 with WRT_KILL_FULL=1 (40 kills, a few minutes).
# Usage: tests/kill.sh BUILD. Prints "kill: N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
bake=$build/wrt-bake
gen=$build/wrt-scenegen
moments=3
[ "${WRT_KILL_FULL:-0}" = 1 ] && moments=10
. tests/lib.sh kill
tmp=$(mktemp -d /tmp/wrt_kill_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/w" "$tmp/keep"
"$gen" maze --out "$tmp/w/maze.gltf" >/dev/null 2>&1 || { ko "wrt-scenegen maze"; summary; exit 1; }
# The older output: a coarser bake of the same scene, and a copy kept elsewhere.
"$bake" "$tmp/w/maze.gltf" -o "$tmp/w/out.gto" -q 1 --quiet >/dev/null 2>&1
cp "$tmp/w/out.gto" "$tmp/keep/older.gto"
opts=(-q 2 --quiet)
check=(--max-error 1 --check-paths 100000)
secs() { local t0 t1; t0=$(date +%s%N); "$@" >/dev/null 2>&1; t1=$(date +%s%N); echo $(( (t1 - t0) / 1000000 )); }
ms_start=$(secs "$bake" --version)  # loading the shared libraries, before main()
ms_plain=$(secs "$bake" "$tmp/w/maze.gltf" -o "$tmp/keep/full.gto" "${opts[@]}")
ms_check=$(secs "$bake" "$tmp/w/maze.gltf" -o "$tmp/keep/full.gto" "${opts[@]}" "${check[@]}")
echo "uninterrupted bake: ${ms_plain} ms, with --max-error ${ms_check} ms; start-up ${ms_start} ms; $moments moments each"
for mode in plain check; do
    total=$ms_plain; extra=()
    [ $mode = check ] && { total=$ms_check; extra=("${check[@]}"); }
    for sig in KILL INT; do
        for ((k = 0; k < moments; k++)); do
            at=$(( total * (2 * k + 1) * 85 / (200 * moments) ))  # within 85 % of the length
            # env --default-signal: a background job of a script starts with SIGINT ignored.
            env --default-signal=INT "$bake" "$tmp/w/maze.gltf" -o "$tmp/w/out.gto" "${opts[@]}" "${extra[@]}" \
                >/dev/null 2>"$tmp/keep/err" &
            pid=$!
            sleep "$(printf '%d.%03d' $((at / 1000)) $((at % 1000)))"
            kill -s $sig $pid 2>/dev/null
            wait $pid 2>/dev/null; rc=$?
            name="$mode SIG$sig at ${at} ms"
            if [ $rc -eq 0 ]; then
                # finished before the signal: the new file replaced the old one, whole
                "$bake" --info "$tmp/w/out.gto" >/dev/null 2>&1 && ok "$name: finished first, new output valid" ||
                    ko "$name: finished first, new output invalid"
                cp "$tmp/keep/older.gto" "$tmp/w/out.gto"
                continue
            fi
            want=137; [ $sig = INT ] && want=4
            # Before main() has run (the dynamic loader, about half a second) the default
            # action of SIGINT applies (exit 130); nothing has been written by then.
            [ $sig = INT ] && [ $rc -eq 130 ] && [ $at -le $((ms_start * 2)) ] && want=130
            [ $rc -eq $want ] && ok "$name: exit $rc" || ko "$name: exit $rc, expected $want"
            cmp -s "$tmp/w/out.gto" "$tmp/keep/older.gto" && ok "$name: older output intact" ||
                ko "$name: older output changed"
            left=$(ls -A "$tmp/w" | grep -vx -e maze.gltf -e out.gto)
            [ -z "$left" ] && ok "$name: no file left behind" || ko "$name: left behind: $left"
            rm -f "$tmp/w"/out.gto.tmp.* 2>/dev/null; cp "$tmp/keep/older.gto" "$tmp/w/out.gto"
        done
    done
done
summary
