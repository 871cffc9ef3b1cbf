#!/usr/bin/env bash
# tools/readme_times.sh BUILD: keeps the README's timings true. Reads the table under
# "## Timings" in README.md (rows `| key | what | CPU s | wall s | ... |`), runs each
# row's command here (the commands are below, one per key), and compares: the measured
# CPU seconds (user + system, all threads; the machine's load moves it little) must be
# within a factor FACTOR (default 2) of the README's, either way. Wall seconds are
# printed beside them and checked only with WALL=1 (a machine shared with other builds
# can stretch them several times). The `make-test` row is compared with the last
# `make test` (tests/run.sh writes BUILD/suite-time.txt), and skipped if there is none.
# Run by `make bench` and `make timings`; ONLY=KEY runs one row (tests/timings.sh: the
# Cornell bake, in `make test`). Prints "timings: N passed, N failed".
set -u
build=${1:-build}
factor=${FACTOR:-2}
cd "$(dirname "$0")/.." || exit 2
tmp=$(mktemp -d /tmp/wrt_times_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
pass=0; fail=0
# cmd KEY: the command a row measures (output into the temporary folder)
cmd() {
    case $1 in
        bake-cornell) echo "$build/wrt-bake assets/cornell.gltf -o $tmp/c.gto --quiet" ;;
        bake-maze) echo "$build/wrt-bake assets/maze.gltf -o $tmp/m.gto --quiet" ;;
        ref-cornell) echo "$build/wrt-ref assets/cornell.gltf --light-pos 0.3,0.8,0.2 --width 640 --height 480 --spp 64 -o $tmp/ref" ;;
        compare-cornell) echo "$build/wrt-compare assets/cornell.gltf $tmp/c.gto -o $tmp/cmp" ;;
        *) echo "" ;;
    esac
}
rows=$(awk '/^## Timings/ { on = 1; next } /^## / { on = 0 } on && /^\| `?[a-z-]+`? \|/' README.md)
[ -n "$rows" ] || { echo "FAIL: no rows under '## Timings' in README.md"; echo "timings: 0 passed, 1 failed"; exit 1; }
while IFS='|' read -r _ key _ cpu wall _; do
    key=$(tr -d ' `' <<<"$key"); cpu=$(tr -d ' ' <<<"$cpu"); wall=$(tr -d ' ' <<<"$wall")
    [ -n "${ONLY:-}" ] && [ "$key" != "$ONLY" ] && continue
    if [ "$key" = make-test ]; then
        if [ ! -s "$build/suite-time.txt" ]; then echo "skipped make-test: no $build/suite-time.txt (run make test first)"; continue; fi
        read -r mc mw <"$build/suite-time.txt"
    else
        c=$(cmd "$key")
        [ -n "$c" ] || { fail=$((fail + 1)); echo "FAIL $key: the README names a timing this check does not know"; continue; }
        /usr/bin/time -f '%U %S %e' -o "$tmp/time" $c >/dev/null 2>&1 || { fail=$((fail + 1)); echo "FAIL $key: $c failed"; continue; }
        read -r u s mw <"$tmp/time"; mc=$(awk -v u="$u" -v s="$s" 'BEGIN { print u + s }')
    fi
    line="$key: CPU $mc s measured, README $cpu s; wall $mw s measured, README $wall s (load $(cut -d' ' -f1 /proc/loadavg))"
    if awk -v m="$mc" -v r="$cpu" -v f="$factor" 'BEGIN { exit !(r > 0 && m <= f * r && m >= r / f) }'; then
        pass=$((pass + 1)); echo "ok $line"
    else
        fail=$((fail + 1)); echo "FAIL $line: CPU not within x$factor"
    fi
    if [ "${WALL:-0}" = 1 ]; then
        if awk -v m="$mw" -v r="$wall" -v f="$factor" 'BEGIN { exit !(r > 0 && m <= f * r && m >= r / f) }'; then
            pass=$((pass + 1)); echo "ok $key: wall within x$factor"
        else fail=$((fail + 1)); echo "FAIL $key: wall $mw s not within x$factor of $wall s"; fi
    fi
done <<<"$rows"
echo "timings: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
