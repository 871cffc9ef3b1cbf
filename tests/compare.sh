#!/usr/bin/env bash
# tests/compare.sh BUILD: wrt-compare on a tiny bake (two facing quads, quality 2): the JSON
# has its keys, the errors are finite and at what this bake measures (cell error 0.019
# debiased, raw 0.036 against a reference floor of 0.030 at these samples; the image at
# 64 paths a pixel is within the reference's own noise), the reference floor is below
# the error, and --max-error works as the pipeline check (exit 5 when not met, 0 when
# met). The accuracy gate proper is tests/test_accuracy.c. Bad inputs are refused before
# any path tracing; the summary line and the panel. Prints "N passed, N failed".
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
# Inputs are checked before the reference is path-traced (the default reference of the
# Cornell box takes tens of CPU seconds): each refusal below exits with its code, says
# what and where in one line, and takes under a second of CPU.
# refused NAME CODE REGEX ARGS...: wrt-compare ARGS exits CODE within 1 CPU second, with
# one line on stderr, starting "wrt-compare: error:" and matching REGEX
refused() {
    local name=$1 code=$2 re=$3 rc cpu lines; shift 3
    /usr/bin/time -f '%U %S' -o "$tmp/time" "$build/wrt-compare" "$@" >"$tmp/out" 2>"$tmp/err"; rc=$?
    cpu=$(awk '{ print $1 + $2 }' "$tmp/time"); lines=$(wc -l <"$tmp/err")
    [ $rc -eq "$code" ]; check_status "$name: exit $code (got $rc)" $?
    awk -v c="$cpu" 'BEGIN { exit !(c < 1) }'; check_status "$name: refused in $cpu s of CPU (< 1)" $?
    [ "$lines" -eq 1 ] && grep -Eq -- "^wrt-compare: error: .*$re" "$tmp/err"
    check_status "$name: one line naming it: $(head -n 1 "$tmp/err")" $?
}
refused "a bake of another scene" 2 "f.gto has 2 quads, the scene assets/cornell.gltf has [0-9]+: it was not baked" \
    assets/cornell.gltf "$tmp/f.gto"
refused "a missing .gto" 2 "nope.gto" assets/cornell.gltf "$tmp/nope.gto"
refused "a bad option value" 1 "bad value for --spp: '0'" assets/cornell.gltf "$tmp/f.gto" --spp 0
refused "an unknown option" 1 "unknown option --frobnicate" assets/cornell.gltf "$tmp/f.gto" --frobnicate
refused "an images folder that does not exist" 3 "-o $tmp/no/dir/cmp: cannot write in the folder" \
    "$scene" "$tmp/f.gto" -o "$tmp/no/dir/cmp"
# The summary line names both figures; the panel is four labelled pictures, each at least
# 320 pixels wide (32-pixel pictures enlarged 10 times, under a label bar).
grep -Eq "f.gto: cell error [0-9.]+ raw, [0-9.]+ debiased \(floor [0-9.]+\); image error [0-9.]+ raw, [0-9.]+ debiased" \
    "$tmp/err.txt"; check_status "summary line: raw and debiased errors, named: $(grep 'cell error' "$tmp/err.txt")" $?
"$build/wrt-compare" "$scene" "$tmp/f.gto" "${args[@]}" -o "$tmp/cmp" >/dev/null 2>&1
check_status "compare -o writes the images" $?
read -r pw ph < <(python3 -c 'import struct,sys; d=open(sys.argv[1],"rb").read(24); print(*struct.unpack(">II", d[16:24]))' "$tmp/cmp_panel.png" 2>/dev/null)
[ "${pw:-0}" -eq $((4 * 320 + 3 * 4)) ] && [ "${ph:-0}" -ge 320 ]; check_status "panel ${pw:-?} x ${ph:-?}: four 320-pixel pictures, 4 apart, under labels" $?
summary
