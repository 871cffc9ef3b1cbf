#!/usr/bin/env bash
# tests/runtime.sh BUILD: the runtime library's tests on bakes made here: the instances
# test (tests/runtime_instances.c) on the two-square scene and a 2 x 2 maze; the public
# API's boundary (tests/runtime_api.c) and the API beside the relighting core
# (tests/runtime_core.c) on the two-square scene and a copy of it whose light has a glTF
# range of 0.75, and the open's progress and cancel on a glossy floor (quality 2); the
# time budget and skip_below (tests/runtime_budget.c) on the maze and the glossy floor. Prints "N passed, N failed" (", N skipped").
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh runtime.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$build/wrt-bake" assets/test/facing.gltf -o "$tmp/a.gto" -q 2 --quiet >/dev/null 2>&1 &&
"$build/wrt-scenegen" maze --cells 2 --seed 3 --out "$tmp/m.gltf" >/dev/null 2>&1 &&
"$build/wrt-bake" "$tmp/m.gltf" -o "$tmp/b.gto" -q 2 --quiet >/dev/null 2>&1 &&
sed 's/"intensity":1}/"intensity":1,"range":0.75}/' assets/test/facing.gltf >"$tmp/r.gltf" &&
grep -q '"range":0.75' "$tmp/r.gltf" &&
"$build/wrt-bake" "$tmp/r.gltf" -o "$tmp/r.gto" -q 2 --quiet >/dev/null 2>&1 &&
"$build/wrt-bake" assets/test/glossy_floor.gltf -o "$tmp/g.gto" -q 2 --quiet >/dev/null 2>&1 || { ko "bakes"; summary; exit 1; }
pass=0; fail=0; skip=0; rc=0
for t in "runtime_instances $tmp/a.gto $tmp/b.gto" "runtime_api $tmp/a.gto $tmp/r.gto $tmp/b.gto --glossy $tmp/g.gto" \
         "runtime_core $tmp/r.gto" "runtime_budget $tmp/b.gto $tmp/g.gto"; do
    set -- $t
    out=$("$build/tests/$1" "${@:2}" 2>&1) || rc=1
    printf '%s\n' "$out"
    line=$(printf '%s\n' "$out" | grep -E '[0-9]+ passed, [0-9]+ failed' | tail -n 1)
    [ -n "$line" ] || { fail=$((fail + 1)); echo "FAIL: $1 printed no count"; continue; }
    pass=$((pass + $(sed -E 's/.* ([0-9]+) passed.*/\1/' <<<"$line")))
    fail=$((fail + $(sed -E 's/.* ([0-9]+) failed.*/\1/' <<<"$line")))
    k=$(sed -nE 's/.* ([0-9]+) skipped.*/\1/p' <<<"$line"); skip=$((skip + ${k:-0}))
done
[ $rc -eq 0 ] || [ $fail -gt 0 ] || fail=1
summary
