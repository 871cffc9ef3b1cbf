#!/usr/bin/env bash
# tests/reconstruct.sh BUILD: the smooth display (common/reconstruct.h) against the path
# tracer, through wrt-compare. Cornell at the default quality, two light positions, a
# 48-pixel image at 1024 paths a pixel (the reference is seeded, the same on any thread
# count): the smooth display's debiased image error was measured at 0.0252 and must stay
# within a point of it, and below the Haar blocks' (0.0378) by at least half a point (the
# finer receiver threshold of quality 5's coarse cells improved the blocks too). A
# Cornell box of 2 x 2 quads a wall (wrt-scenegen --res 2): no jump across the shared
# edges (measured 0) where the Haar blocks jump more across them than inside a quad.
# Prints "N passed, N failed". Half a minute on 2 busy cores.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh reconstruct.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# The first number after a key in the first bake's figures (its means).
num() { grep -o '"bakes":\[{.*' "$1" | grep -o "\"$2\":[-0-9.eE+naif]*" | head -n 1 | cut -d: -f2; }

"$build/wrt-bake" assets/cornell.gltf -o "$tmp/c.gto" --quiet >/dev/null 2>&1
check_status "bake cornell" $?
"$build/wrt-compare" assets/cornell.gltf "$tmp/c.gto" --lights 2 --cell-paths 100000 --width 48 --spp 1024 \
    --cells 8 --bench 1 >"$tmp/c.json" 2>/dev/null
check_status "compare cornell" $?
s=$(num "$tmp/c.json" image_rmse_debiased); h=$(num "$tmp/c.json" image_rmse_haar_debiased)
echo "cornell: smooth image error $s (debiased), Haar blocks $h"
awk -v s="$s" 'BEGIN{exit !(s == s + 0 && s >= 0 && s <= 0.0252 + 0.01)}'
check_status "smooth image error $s within a point of the measured 0.0252" $?
awk -v s="$s" -v h="$h" 'BEGIN{exit !(h == h + 0 && h >= s + 0.005)}'
check_status "Haar blocks' image error $h at least half a point above the smooth display's $s" $?

"$build/wrt-scenegen" cornell --res 2 --out "$tmp/r2.gltf" >/dev/null 2>&1
check_status "scenegen --res 2" $?
"$build/wrt-bake" "$tmp/r2.gltf" -o "$tmp/r2.gto" -q 2 --quiet >/dev/null 2>&1
check_status "bake cornell --res 2" $?
"$build/wrt-compare" "$tmp/r2.gltf" "$tmp/r2.gto" --lights 1 --cell-paths 20000 --width 16 --spp 16 --bench 1 \
    >"$tmp/r2.json" 2>/dev/null
check_status "compare cornell --res 2" $?
a=$(num "$tmp/r2.json" seam_across); i=$(num "$tmp/r2.json" seam_inside)
ha=$(num "$tmp/r2.json" seam_across_haar); hi=$(num "$tmp/r2.json" seam_inside_haar)
echo "cornell --res 2: jump across shared edges $a, inside quads $i; Haar blocks $ha and $hi"
awk -v a="$a" -v i="$i" 'BEGIN{exit !(a == a + 0 && i > 0 && a <= 1e-6 * i)}'
check_status "no seam: jump across shared edges $a against $i inside" $?
awk -v a="$ha" -v i="$hi" 'BEGIN{exit !(a == a + 0 && a > 1.5 * i)}'
check_status "the Haar blocks show seams ($ha across, $hi inside): the measure sees them" $?
summary
