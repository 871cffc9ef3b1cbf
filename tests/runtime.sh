#!/usr/bin/env bash
# tests/runtime.sh BUILD: the runtime library's instances test (tests/runtime_instances.c)
# on two bakes made here: the two-square scene and a 2 x 2 maze. Prints "N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh runtime.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$build/wrt-bake" assets/test/facing.gltf -o "$tmp/a.gto" -q 2 --quiet >/dev/null 2>&1 &&
"$build/wrt-scenegen" maze --cells 2 --seed 3 --out "$tmp/m.gltf" >/dev/null 2>&1 &&
"$build/wrt-bake" "$tmp/m.gltf" -o "$tmp/b.gto" -q 2 --quiet >/dev/null 2>&1 || { ko "bakes"; summary; exit 1; }
"$build/tests/runtime_instances" "$tmp/a.gto" "$tmp/b.gto"
