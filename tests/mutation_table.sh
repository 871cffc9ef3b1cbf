#!/usr/bin/env bash
# tests/mutation_table.sh BUILD: the mutation run's table and its runner, in seconds (the
# run itself is `make mutate`, which CI runs whole). Every entry's snippet must still
# occur exactly once in its file (a stale entry is a fault that silently stops being
# tested); the runner must refuse an id it does not know and must not take a build folder
# that does not exist yet for a fault id (a fresh clone once ran "0 caught, 0 survived"
# and passed). Prints "N passed, N failed".
cd "$(dirname "$0")/.."
. tests/lib.sh mutation_table.sh
# check STATUS WHAT: counts one check, naming WHAT when it failed
check() { if [ "$1" = 0 ]; then ok; else ko "$2"; fi; }
out=$(bash tests/mutate.sh --check 2>&1); rc=$?
check $rc "mutate --check: $out"
n=$(sed -nE 's/^mutate --check: ([0-9]+) faults.*/\1/p' <<<"$out")
[ "${n:-0}" -ge 30 ]; check $? "the table has ${n:-0} faults, fewer than 30"
nodir=$(mktemp -u /tmp/wrt_mutate_nodir_XXXXXX)
out=$(bash tests/mutate.sh "$nodir" 2>&1); rc=$?
[ $rc -eq 1 ] && grep -q "no fault named" <<<"$out"; check $? "a missing build folder given positionally was not refused (rc $rc): $out"
[ ! -e "$nodir" ]; check $? "the refused run created $nodir"
out=$(bash tests/mutate.sh --build "$nodir" --min-score 101 2>&1); rc=$?
[ $rc -eq 1 ] && grep -q "percentage" <<<"$out"; check $? "--min-score 101 was not refused (rc $rc): $out"
rm -rf "$nodir"
summary
