#!/usr/bin/env bash
# Runs every test program in BUILD/tests (and the shell tests in tests/*.sh), then prints
# the total as "N passed, N failed", the line CI reads, followed by ", N skipped" when a
# check could not run here (each skipped check says why). Each program's line ends with its
# CPU seconds (its processes', user + system, from /proc) and wall seconds, and the total
# line is preceded by the whole suite's, so that the line CI reads stays the last.
# WRT_TEST_LOGS=DIR keeps each program's output in DIR/NAME.out (tests/claims.sh --write
# reads them). Usage: tests/run.sh BUILD [stress]
set -u
build=${1:-build}
export WRT_BUILD=$build
pass=0; fail=0; skip=0; failed_names=()
logs=${WRT_TEST_LOGS:-}   # a folder: each program's output is kept there as NAME.out
[ -n "$logs" ] && mkdir -p "$logs"
# skipped COUNT-LINE: the N of a trailing ", N skipped", else 0
skipped() { local n; n=$(sed -nE 's/.* ([0-9]+) skipped.*/\1/p' <<<"$1"); echo "${n:-0}"; }
cd "$(dirname "$0")/.."
# cpu_ticks: the CPU clock ticks of this shell's waited-for children (cutime + cstime);
# fields 16 and 17 of /proc/PID/stat (the command name before them, bash, has no space).
hz=$(getconf CLK_TCK 2>/dev/null || echo 100)
cpu_ticks() { local f; read -r -a f </proc/$$/stat; echo $((f[15] + f[16])); }
t0_cpu=$(cpu_ticks); t0_wall=$EPOCHREALTIME
c0=0; w0=0
begin() { c0=$(cpu_ticks); w0=$EPOCHREALTIME; }
# took: "  (cpu C s, wall W s)" since begin
took() { awk -v c=$(( $(cpu_ticks) - c0 )) -v hz="$hz" -v w0="$w0" -v w1="$EPOCHREALTIME" \
             'BEGIN { printf "  (cpu %.1f s, wall %.1f s)", c / hz, w1 - w0 }'; }
for t in "$build"/tests/test_*; do
    [ -x "$t" ] || continue
    begin; out=$("$t" 2>&1); rc=$?; tm=$(took)
    [ -n "$logs" ] && printf '%s\n' "$out" >"$logs/$(basename "$t").out"
    line=$(printf '%s\n' "$out" | grep -E '[0-9]+ passed, [0-9]+ failed' | tail -n 1)
    p=$(sed -E 's/^(.*[^0-9])?([0-9]+) passed, ([0-9]+) failed.*/\2/' <<<"$line")
    f=$(sed -E 's/^(.*[^0-9])?([0-9]+) passed, ([0-9]+) failed.*/\3/' <<<"$line")
    [[ "$p" =~ ^[0-9]+$ ]] || p=0
    [[ "$f" =~ ^[0-9]+$ ]] || f=0
    if [ $rc -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi   # a crash counts as a failure
    k=$(skipped "$line"); skip=$((skip + k))
    if [ $((p + f + k)) -eq 0 ]; then f=1; echo "$t: no 'N passed, N failed' line: counted as a failure"; fi
    pass=$((pass + p)); fail=$((fail + f))
    if [ "$f" -ne 0 ]; then failed_names+=("$t"); printf '%s\n' "$out" | grep -E 'FAIL|not ok|ERROR|Sanitizer' | head -n 20; fi
    [ "$k" -gt 0 ] && printf '%s\n' "$out" | grep -E '^skipped' | head -n 10
    printf '%-40s %4d passed, %d failed%s%s\n' "$(basename "$t")" "$p" "$f" "$([ "$k" -gt 0 ] && echo ", $k skipped")" "$tm"
done
for s in tests/*.sh; do
    case "$(basename "$s")" in run.sh|mutate.sh|lib.sh) continue ;; esac   # mutate.sh: `make mutate`; lib.sh: the helpers
    begin; out=$(bash "$s" "$build" 2>&1); rc=$?; tm=$(took)
    [ -n "$logs" ] && printf '%s\n' "$out" >"$logs/$(basename "$s" .sh).out"
    line=$(printf '%s\n' "$out" | grep -E '[0-9]+ passed, [0-9]+ failed' | tail -n 1)
    p=$(sed -E 's/^(.*[^0-9])?([0-9]+) passed, ([0-9]+) failed.*/\2/' <<<"$line"); [[ "$p" =~ ^[0-9]+$ ]] || p=0
    f=$(sed -E 's/^(.*[^0-9])?([0-9]+) passed, ([0-9]+) failed.*/\3/' <<<"$line"); [[ "$f" =~ ^[0-9]+$ ]] || f=0
    if [ $rc -ne 0 ] && [ "$f" -eq 0 ]; then f=1; fi
    k=$(skipped "$line"); skip=$((skip + k))
    if [ $((p + f + k)) -eq 0 ]; then f=1; echo "$s: no 'N passed, N failed' line: counted as a failure"; fi
    pass=$((pass + p)); fail=$((fail + f))
    if [ "$f" -ne 0 ]; then failed_names+=("$s"); printf '%s\n' "$out" | grep -E 'FAIL' | head -n 20; fi
    [ "$k" -gt 0 ] && printf '%s\n' "$out" | grep -E '^skipped' | head -n 10
    printf '%-40s %4d passed, %d failed%s%s\n' "$(basename "$s")" "$p" "$f" "$([ "$k" -gt 0 ] && echo ", $k skipped")" "$tm"
done
[ ${#failed_names[@]} -eq 0 ] || echo "failing: ${failed_names[*]}"
c0=$t0_cpu; w0=$t0_wall; echo "suite time:$(took)"
# the suite's CPU and wall seconds, for tools/readme_times.sh (README "Timings": make test)
[ -z "${2:-}" ] && [ -d "$build" ] && awk -v c=$(( $(cpu_ticks) - c0 )) -v hz="$hz" -v w0="$w0" -v w1="$EPOCHREALTIME" \
    'BEGIN { printf "%.1f %.1f\n", c / hz, w1 - w0 }' >"$build/suite-time.txt"
if [ "$skip" -gt 0 ]; then echo "$pass passed, $fail failed, $skip skipped"; else echo "$pass passed, $fail failed"; fi
[ "$fail" -eq 0 ]
