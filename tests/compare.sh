#!/usr/bin/env bash
# tests/compare.sh BUILD: wrt-compare on a tiny bake (two facing quads, quality 2): the JSON
# has its keys, the errors are finite and at what this bake measures (cell error 0.019
# debiased, raw 0.036 against a reference floor of 0.030 at these samples; the image at
# 64 paths a pixel is within the reference's own noise), the reference floor is below
# the error, and --max-error works as the pipeline check (exit 5 when not met, 0 when
# met). The accuracy gate proper is tests/test_accuracy.c. Prints "N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh compare.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scene=assets/test/facing.gltf
"$build/wrt-bake" "$scene" -o "$tmp/f.gto" -q 2 --quiet >/dev/null 2>&1
check_status "bake" $?
args=(--lights 2 --cell-paths 200000 --width 32 --spp 64 --bench 3)
"$build/wrt-compare" "$scene" "$tmp/f.gto" "${args[@]}" >"$tmp/out.json" 2>"$tmp/err.txt"
check_status "compare exits 0" $?
json=$(cat "$tmp/out.json")
for key in scene lights reference cell_floor image_floor bakes cell_rmse cell_rmse_debiased image_rmse \
           image_rmse_debiased ms_per_light_change per_light bytes ok; do
    grep -q "\"$key\":" <<<"$json"; check_status "key $key" $?
done
# The first number after a key, as awk reads it.
num() { grep -o "\"$1\":[-0-9.eE+naif]*" <<<"$json" | head -n 1 | cut -d: -f2; }
cell=$(num cell_rmse); img=$(num image_rmse); deb=$(num cell_rmse_debiased); ifl=$(num image_floor); fl=$(grep -o '"bakes":\[{.*' <<<"$json" | grep -o '"cell_floor":[-0-9.eE+]*' | head -n 1 | cut -d: -f2)
awk -v c="$deb" 'BEGIN{exit !(c == c + 0 && c >= 0 && c <= 0.03)}'; check_status "cell rmse debiased $deb <= 0.03 (measured 0.019)" $?
awk -v c="$img" -v f="$ifl" 'BEGIN{exit !(c == c + 0 && c >= 0 && c <= 1.1 * f + 0.05)}'; check_status "image rmse $img within the reference's noise $ifl" $?
awk -v c="$cell" -v f="$fl" 'BEGIN{exit !(f > 0 && f < c)}'; check_status "cell floor $fl below the error $cell" $?
"$build/wrt-compare" "$scene" "$tmp/f.gto" "${args[@]}" --no-image --max-error 1e-9 >"$tmp/strict.json" 2>/dev/null
rc=$?; [ $rc -eq 5 ]; check_status "--max-error 1e-9 exits 5 (got $rc)" $?
grep -q '"within_max_error":false' "$tmp/strict.json"; check_status "strict JSON says not within" $?
"$build/wrt-compare" "$scene" "$tmp/f.gto" "${args[@]}" --no-image --max-error 0.9 >/dev/null 2>&1
rc=$?; [ $rc -eq 0 ]; check_status "--max-error 0.9 exits 0 (got $rc)" $?
"$build/wrt-compare" assets/cornell.gltf "$tmp/f.gto" --no-image --cell-paths 1000 --lights 1 >/dev/null 2>&1
rc=$?; [ $rc -eq 2 ]; check_status "a bake of another scene is refused with 2 (got $rc)" $?
summary
