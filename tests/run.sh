#!/usr/bin/env bash
# Runs every test program in BUILD/tests (and the shell tests in tests/*.sh), then prints
# the total as "N passed, N failed", the line CI reads, followed by ", N skipped" when a
# check could not run here (each skipped check says why). WRT_TEST_LOGS=DIR keeps each
# program's output in DIR/NAME.out (tests/claims.sh --write reads them). Usage: tests/run.sh BUILD [stress]
set -u
build=${1:-build}
export WRT_BUILD=$build
pass=0; fail=0; skip=0; failed_names=()
logs=${WRT_TEST_LOGS:-}   # a folder: each program's output is kept there as NAME.out
[ -n "$logs" ] && mkdir -p "$logs"
# skipped COUNT-LINE: the N of a trailing ", N skipped", else 0
skipped() { local n; n=$(sed -nE 's/.* ([0-9]+) skipped.*/\1/p' <<<"$1"); echo "${n:-0}"; }
cd "$(dirname "$0")/.."
for t in "$build"/tests/test_*; do
    [ -x "$t" ] || continue
    out=$("$t" 2>&1); rc=$?
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
    printf '%-40s %4d passed, %d failed%s\n' "$(basename "$t")" "$p" "$f" "$([ "$k" -gt 0 ] && echo ", $k skipped")"
done
for s in tests/*.sh; do
    case "$(basename "$s")" in run.sh|mutate.sh|lib.sh) continue ;; esac   # mutate.sh: `make mutate`; lib.sh: the helpers
    out=$(bash "$s" "$build" 2>&1); rc=$?
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
    printf '%-40s %4d passed, %d failed%s\n' "$(basename "$s")" "$p" "$f" "$([ "$k" -gt 0 ] && echo ", $k skipped")"
done
[ ${#failed_names[@]} -eq 0 ] || echo "failing: ${failed_names[*]}"
if [ "$skip" -gt 0 ]; then echo "$pass passed, $fail failed, $skip skipped"; else echo "$pass passed, $fail failed"; fi
[ "$fail" -eq 0 ]
