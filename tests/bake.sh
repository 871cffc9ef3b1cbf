#!/usr/bin/env bash
# bake.sh: end-to-end tests of the wrt-bake command line: a bake and its --json figures,
# the effect counters of a diffuse scene, identical bytes with 1 and 2 threads
# (by default; timings only with --provenance-timings), --info on good and damaged files
# with distinct errors, bad scenes and absurd options refused with a message and the
# documented exit code, the output checked before the work (never an input, a writable
# folder), non-regular inputs refused without blocking, the --max-error check file
# private, a memory budget refused with the figure named (exit 7) and the peak memory
# covered by the estimate, and an interrupted bake leaving no output and no temporary
# behind (exit 4).
# Usage: tests/bake.sh BUILD. Prints "bake: N passed, N failed"; non-zero exit on a failure.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
bake=$build/wrt-bake
gen=$build/wrt-scenegen
. tests/lib.sh bake
lib_ko_shows_err=1 # a failure shows what the command said
tmp=$(mktemp -d /tmp/wrt_bake_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
asan=0; nm "$build/wrt-bake" 2>/dev/null | grep -q __asan_init && asan=1
jnum() { tr -d '\n' < "$2" | grep -o "\"$1\":[0-9.e+-]*" | head -n 1 | cut -d: -f2; }

check "--help" "$bake" --help
check "--version" "$bake" --version
expect_exit "no output file: exit 1" 1 "no output" "$bake" assets/cornell.gltf
expect_exit "quality 0 refused: exit 1" 1 "quality.*\[1, 9\]" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --quality 0
expect_exit "absurd threads refused: exit 1" 1 "threads" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --threads 100000
expect_exit "NaN threshold refused: exit 1" 1 "eps-compress" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --eps-compress nan
expect_exit "NaN coarse receiver threshold refused: exit 1" 1 "eps-receiver-coarse" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --eps-receiver-coarse nan
# The receiver's threshold for the cells the display keeps (coarser than 8 x 8 a quad):
# 3.3 times finer from quality 5 on, the same below; an explicit --eps-receiver sets both.
cfg() { "$bake" "$@" --print-config 2>/dev/null | tr -d '\n'; }
c5=$(cfg -q 5); c4=$(cfg -q 4); ce=$(cfg -q 5 --eps-receiver 0.02); cc=$(cfg -q 5 --eps-receiver-coarse 0.001)
printf '%s' "$c5" | grep -q '"eps_receiver":0.01,"eps_receiver_coarse":0.003,' && ok "quality 5: receiver 0.01, coarse cells 0.003" || ko "quality 5 config: $c5"
printf '%s' "$c4" | grep -q '"eps_receiver":0.02,"eps_receiver_coarse":0.02,' && ok "quality 4: one receiver threshold" || ko "quality 4 config: $c4"
printf '%s' "$ce" | grep -q '"eps_receiver":0.02,"eps_receiver_coarse":0.02,' && ok "--eps-receiver alone sets both" || ko "--eps-receiver config: $ce"
printf '%s' "$cc" | grep -q '"eps_receiver":0.01,"eps_receiver_coarse":0.001,' && ok "--eps-receiver-coarse alone" || ko "--eps-receiver-coarse config: $cc"
expect_exit "unknown option: exit 1" 1 "unknown option" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --frobnicate
expect_exit "glossy quality above the quality refused: exit 1" 1 "glossy-quality 5 must not exceed the quality \(3\)" "$bake" assets/glossy.gltf -o "$tmp/x.gto" -q 3 --glossy-quality 5
# --eps-final: below the products' threshold refused; above it, the stored operator alone
# loses its smallest entries (the products' figures unchanged), and the file is smaller
expect_exit "--eps-final below --eps-compress refused: exit 1" 1 "eps-final 1e-06 is below the products' threshold" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --eps-final 1e-6
if "$bake" assets/cornell.gltf -q 2 -o "$tmp/ef0.gto" --json --quiet >"$tmp/ef0.json" 2>/dev/null &&
   "$bake" assets/cornell.gltf -q 2 -o "$tmp/ef1.gto" --json --quiet --eps-final 0.01 >"$tmp/ef1.json" 2>/dev/null; then
    e0=$(grep -o '"gto":[0-9]*' "$tmp/ef0.json" | tail -n 1 | cut -d: -f2); e1=$(grep -o '"gto":[0-9]*' "$tmp/ef1.json" | tail -n 1 | cut -d: -f2)
    d0=$(grep -o '"dto":[0-9]*' "$tmp/ef0.json" | tail -n 1 | cut -d: -f2); d1=$(grep -o '"dto":[0-9]*' "$tmp/ef1.json" | tail -n 1 | cut -d: -f2)
    [ -n "$e0" ] && [ -n "$e1" ] && [ "$e1" -lt "$e0" ] && [ "$d0" = "$d1" ] && [ "$(stat -c %s "$tmp/ef1.gto")" -lt "$(stat -c %s "$tmp/ef0.gto")" ] &&
        grep -q '"eps_final":0.01' "$tmp/ef1.json" && ok "--eps-final 0.01: $e0 -> $e1 stored entries, DTO $d0 both" || ko "--eps-final: $e0 -> $e1, DTO $d0 $d1"
else
    ko "bakes with and without --eps-final"
fi
# the drop rule of the stored operator (drop_rule.h): on by default (sender 0.5, receiver
# 1 from depth 3); 0 turns each part off, the uniform threshold of before, which stores
# more entries; the products' figures are the same; out of range refused
expect_exit "--drop-sender 5 refused: exit 1" 1 "drop-sender" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --drop-sender 5
if "$bake" assets/cornell.gltf -q 2 -o "$tmp/dr1.gto" --json --quiet --drop-sender 0 --drop-receiver 0 >"$tmp/dr1.json" 2>/dev/null; then
    e1=$(grep -o '"gto":[0-9]*' "$tmp/dr1.json" | tail -n 1 | cut -d: -f2)
    d1=$(grep -o '"dto":[0-9]*' "$tmp/dr1.json" | tail -n 1 | cut -d: -f2)
    [ -n "$e0" ] && [ -n "$e1" ] && [ "$e0" -lt "$e1" ] && [ "$d0" = "$d1" ] &&
        grep -q '"drop_sender":0.5,"drop_receiver":1,"drop_receiver_from":3' "$tmp/ef0.json" &&
        grep -q '"drop_sender":0,"drop_receiver":0,"drop_receiver_from":3' "$tmp/dr1.json" &&
        ok "drop rule: $e1 stored entries without it, $e0 with it (the default), DTO $d0 both" ||
        ko "drop rule: $e1 without, $e0 with, DTO $d0 $d1"
else
    ko "bake with --drop-sender 0 --drop-receiver 0"
fi
# the first-bounce operator: written for glossy quads at the lobe's level (3 for the
# glossy asset's floor, roughness 0.3), none with --first-bounce-level 0 (no K sections;
# both files are version 3.0 for their compact entries, with the quad-to-source map)
if "$bake" assets/glossy.gltf -q 1 -o "$tmp/k.gto" --quiet >/dev/null 2>&1 &&
   "$bake" assets/glossy.gltf -q 1 -o "$tmp/k0.gto" --first-bounce-level 0 --quiet >/dev/null 2>&1; then
    k=$("$bake" --info "$tmp/k.gto" --json | jq -r '"\(.version) \(.first_bounce.max_angular_node_level)"')
    k0=$("$bake" --info "$tmp/k0.gto" --json | jq -r '"\(.version) \(.first_bounce) \(.source_map != null)"')
    [ "$k" = "3.0 2" ] && ok "glossy bake: first-bounce operator to outgoing level 3 ($k)" || ko "glossy bake: first-bounce operator ($k)"
    [ "$k0" = "3.0 null true" ] && ok "--first-bounce-level 0: no K, the source map (3.0)" || ko "--first-bounce-level 0: $k0"
else
    ko "glossy bakes with and without the first-bounce operator"
fi
# format 3.0 (the default) and --compact-v2 (2.0, for a 2.x reader): the same decoded
# operator, every key, row and value bit (tools/gto_same), the 3.0 file the smaller
if "$bake" assets/glossy.gltf -q 1 -o "$tmp/f3.gto" --quiet >/dev/null 2>&1 &&
   "$bake" assets/glossy.gltf -q 1 -o "$tmp/f2.gto" --compact-v2 --quiet >/dev/null 2>&1; then
    v=$("$bake" --info "$tmp/f3.gto" --json | jq -r .version)/$("$bake" --info "$tmp/f2.gto" --json | jq -r .version)
    same=$("$build/tools/gto_same" "$tmp/f2.gto" "$tmp/f3.gto" 2>&1)
    s3=$(stat -c %s "$tmp/f3.gto"); s2=$(stat -c %s "$tmp/f2.gto")
    [ "$v" = "3.0/2.0" ] && [[ "$same" == *"the same operator"* ]] && [ "$s3" -lt "$s2" ] &&
        ok "3.0 and --compact-v2's 2.0: the same operator, $s3 < $s2 bytes" || ko "3.0 against 2.0: $v, $s3 / $s2 bytes: $same"
else
    ko "glossy bakes as 3.0 and 2.0"
fi
expect_exit "first-bounce level 5 refused: exit 1" 1 "first-bounce-level.*\[0, 4\]" "$bake" assets/glossy.gltf -o "$tmp/x.gto" --first-bounce-level 5
expect_exit "memory budget 0 refused: exit 1" 1 "max-memory.*\[1," "$bake" assets/cornell.gltf -o "$tmp/x.gto" --max-memory 0
expect_exit "min level above max level: exit 1" 1 "deeper" "$bake" assets/cornell.gltf -o "$tmp/x.gto" --min-level 5 --max-level 3
expect_exit "missing scene: exit 2" 2 "nope.gltf" "$bake" "$tmp/nope.gltf" -o "$tmp/x.gto"
printf '{"asset":{"version":"2.0"},"meshes":[' > "$tmp/broken.gltf"
expect_exit "malformed glTF: exit 2" 2 "broken.gltf" "$bake" "$tmp/broken.gltf" -o "$tmp/x.gto"
[ ! -e "$tmp/x.gto" ] && ok "nothing written on failure" || ko "nothing written on failure"

# A bake with figures.
if "$bake" assets/test/facing.gltf -o "$tmp/f.gto" --json --quiet >"$tmp/f.json" 2>"$tmp/err"; then
    ok "facing bake"
    for k in dto gto total links entries bytes bounces rays energy_left angular; do
        grep -q "\"$k\"" "$tmp/f.json" && ok "json has $k" || ko "json has $k"
    done
    [ "$(jnum traced "$tmp/f.json")" = 0 ] && ok "no occluder: no rays traced" || ko "no occluder: no rays traced"
    [ "$(jnum angular "$tmp/f.json")" = 0 ] && ok "diffuse: no angular entries" || ko "diffuse: no angular entries"
    bytes=$(jnum bytes "$tmp/f.json"); real=$(stat -c %s "$tmp/f.gto")
    [ "$bytes" = "$real" ] && ok "bytes reported = file size ($real)" || ko "bytes reported ($bytes) = file size ($real)"
else
    ko "facing bake"
fi

# The power balance: a closed scene is found closed, an open one open; --no-balance
# leaves T as the links computed it.
if "$bake" assets/test/furnace.gltf -o "$tmp/fu.gto" --quality 2 --json --quiet >"$tmp/fu.json" 2>"$tmp/err" &&
   "$bake" assets/test/furnace.gltf -o "$tmp/fu0.gto" --quality 2 --json --quiet --no-balance >"$tmp/fu0.json" 2>>"$tmp/err"; then
    grep -q '"closed":true' "$tmp/fu.json" && ok "furnace: found closed" || ko "furnace: found closed"
    grep -q '"closed":false' "$tmp/f.json" && ok "facing squares: found open" || ko "facing squares: found open"
    [ "$(jnum balance_entries "$tmp/fu.json")" -gt 0 ] && ok "balance sets entries" || ko "balance sets entries"
    [ "$(jnum balance_entries "$tmp/fu0.json")" = 0 ] && grep -q '"balance":0' "$tmp/fu0.json" &&
        ok "--no-balance: no entries set, recorded in the options" || ko "--no-balance: no entries set, recorded"
else
    ko "furnace bakes"; head -c 300 "$tmp/err"
fi

# Same bytes whatever the thread count, by default (timings only on request).
"$bake" assets/cornell.gltf -o "$tmp/t1.gto" --quality 2 --threads 1 --quiet >/dev/null 2>"$tmp/err"
"$bake" assets/cornell.gltf -o "$tmp/t2.gto" --quality 2 --threads 2 --quiet >/dev/null 2>>"$tmp/err"
cmp -s "$tmp/t1.gto" "$tmp/t2.gto" && ok "1 and 2 threads: identical bytes" || ko "1 and 2 threads: identical bytes"
"$bake" assets/glossy.gltf -o "$tmp/g1.gto" --quality 2 --threads 1 --quiet >/dev/null 2>"$tmp/err"
"$bake" assets/glossy.gltf -o "$tmp/g2.gto" --quality 2 --threads 2 --quiet >/dev/null 2>>"$tmp/err"
cmp -s "$tmp/g1.gto" "$tmp/g2.gto" && ok "glossy, 1 and 2 threads: identical bytes" || ko "glossy, 1 and 2 threads: identical bytes"
"$bake" assets/cornell.gltf -o "$tmp/t3.gto" --quality 2 --threads 2 --provenance-timings --quiet >/dev/null 2>>"$tmp/err"
"$bake" --info "$tmp/t3.gto" --json > "$tmp/t3.json" 2>>"$tmp/err"
"$bake" --info "$tmp/t1.gto" --json > "$tmp/t1.json" 2>>"$tmp/err"
grep -q '"seconds":{"dto"' "$tmp/t3.json" && ! grep -q '"seconds":{"dto"' "$tmp/t1.json" &&
    ok "--provenance-timings stores the timings, the default does not" || ko "--provenance-timings stores the timings, the default does not"

# --info on good and damaged files.
check "--info on a good file" "$bake" --info "$tmp/t1.gto"
grep -qi "ok" "$tmp/out" && ok "--info reports the integrity check" || ko "--info reports the integrity check"
check "--info --json" "$bake" --info "$tmp/t1.gto" --json
size=$(stat -c %s "$tmp/t1.gto")
head -c $((size / 2)) "$tmp/t1.gto" > "$tmp/trunc.gto"
expect_exit "truncated file: exit 2" 2 "truncated" "$bake" --info "$tmp/trunc.gto"
cp "$tmp/t1.gto" "$tmp/flip.gto"
printf '\xff' | dd of="$tmp/flip.gto" bs=1 seek=$((size - 100)) conv=notrunc 2>/dev/null
expect_exit "flipped byte: exit 2, checksum" 2 "checksum" "$bake" --info "$tmp/flip.gto"
printf 'GIF89a not a transport file at all' > "$tmp/foreign.gto"
expect_exit "foreign file: exit 2" 2 "not a .gto" "$bake" --info "$tmp/foreign.gto"

# The accuracy check: a generous limit passes and writes, an impossible one exits 5 and
# leaves nothing.
"$bake" assets/cornell.gltf -o "$tmp/ok.gto" --quality 2 --max-error 0.6 --check-paths 200000 --json --quiet >"$tmp/c.json" 2>"$tmp/err"
[ $? -eq 0 ] && [ -s "$tmp/ok.gto" ] && grep -q '"check"' "$tmp/c.json" && ok "--max-error met: written, figures in JSON" || ko "--max-error met: written, figures in JSON"
expect_exit "--max-error not met: exit 5" 5 "accuracy not met" "$bake" assets/cornell.gltf -o "$tmp/bad.gto" --quality 2 --max-error 0.001 --check-paths 200000
[ ! -e "$tmp/bad.gto" ] && [ ! -e "$tmp/bad.gto.check" ] && ok "rejected bake leaves nothing" || ko "rejected bake leaves nothing"

# The output is never an input, and is checked before the work.
cp assets/test/facing.gltf "$tmp/scene.gltf"; cp "$tmp/scene.gltf" "$tmp/scene.orig"
ln -f "$tmp/scene.gltf" "$tmp/hard.gto"; ln -sf "$tmp/scene.gltf" "$tmp/sym.gto"
expect_exit "-o names the scene: exit 1" 1 "the output is the input" "$bake" "$tmp/scene.gltf" -o "$tmp/scene.gltf"
expect_exit "-o is a hard link to the scene: exit 1" 1 "the output is the input" "$bake" "$tmp/scene.gltf" -o "$tmp/hard.gto"
expect_exit "-o is a symbolic link to the scene: exit 1" 1 "the output is the input" "$bake" "$tmp/scene.gltf" -o "$tmp/sym.gto"
cmp -s "$tmp/scene.gltf" "$tmp/scene.orig" && ok "the scene is intact" || ko "the scene is intact"
# ... nor a file the scene reads (an external buffer).
b64=$(grep -o 'base64,[A-Za-z0-9+/=]*' tests/data/quad.gltf | head -n 1 | cut -d, -f2)
printf '%s' "$b64" | base64 -d > "$tmp/q.bin"; cp "$tmp/q.bin" "$tmp/q.orig"
sed "s|data:application/octet-stream;base64,[A-Za-z0-9+/=]*|q.bin|" tests/data/quad.gltf > "$tmp/ext.gltf"
"$bake" --scan "$tmp/ext.gltf" >/dev/null 2>"$tmp/err" && ok "scene with an external buffer loads" || ko "scene with an external buffer loads"
expect_exit "-o names the scene's buffer: exit 1" 1 "q.bin: the output is the input" "$bake" "$tmp/ext.gltf" -o "$tmp/q.bin"
cmp -s "$tmp/q.bin" "$tmp/q.orig" && ok "the buffer is intact" || ko "the buffer is intact"
expect_exit "-o given twice: exit 1" 1 "-o given twice" "$bake" assets/cornell.gltf -o "$tmp/a.gto" -o "$tmp/b.gto"
expect_exit "--quality given twice: exit 1" 1 "given twice" "$bake" assets/cornell.gltf -o "$tmp/a.gto" -q 2 --quality 3
expect_exit "-o is a directory: exit 3" 3 "the output is a directory" "$bake" assets/cornell.gltf -o "$tmp"
"$gen" maze --out "$tmp/maze.gltf" >/dev/null 2>&1
t0=$(date +%s%N)
expect_exit "unwritable output folder: exit 3" 3 "cannot create a temporary file" "$bake" "$tmp/maze.gltf" -o /proc/wrt_no.gto --quality 6
ms=$(( ($(date +%s%N) - t0) / 1000000 ))
[ "$ms" -lt 2000 ] && ok "unwritable folder refused before the bake (${ms} ms)" || ko "unwritable folder refused before the bake (${ms} ms)"
mkfifo "$tmp/pipe.gltf" "$tmp/pipe.gto"; mkdir "$tmp/dir.gltf"
expect_exit "FIFO scene: exit 2, no hang" 2 "not a regular file \(a FIFO\)" timeout 10 "$bake" "$tmp/pipe.gltf" -o "$tmp/x.gto"
expect_exit "FIFO --scan: exit 2, no hang" 2 "not a regular file \(a FIFO\)" timeout 10 "$bake" --scan "$tmp/pipe.gltf"
expect_exit "FIFO --info: exit 2, no hang" 2 "not a regular file \(a FIFO\)" timeout 10 "$bake" --info "$tmp/pipe.gto"
expect_exit "directory scene: exit 2" 2 "not a regular file \(a directory\)" "$bake" "$tmp/dir.gltf" -o "$tmp/x.gto"
expect_exit "camera position = target: exit 1" 1 "no view direction" "$build/wrt-play" "$tmp/t1.gto" --headless --out "$tmp/x.png" --camera-pos 1,2,3 --camera-target 1,2,3
# The check file of --max-error is private: a user's file of the old fixed name is kept,
# and two checked bakes to one output do not read each other's file.
echo "mine" > "$tmp/two.gto.check"
"$bake" assets/cornell.gltf -o "$tmp/two.gto" --quality 2 --max-error 0.6 --check-paths 200000 --quiet >/dev/null 2>"$tmp/err" & p1=$!
"$bake" assets/cornell.gltf -o "$tmp/two.gto" --quality 2 --max-error 0.6 --check-paths 200000 --quiet >/dev/null 2>>"$tmp/err" & p2=$!
wait $p1; r1=$?; wait $p2; r2=$?
[ $r1 -eq 0 ] && [ $r2 -eq 0 ] && "$bake" --info "$tmp/two.gto" >/dev/null 2>>"$tmp/err" &&
    ok "two checked bakes to one output both succeed" || ko "two checked bakes to one output both succeed ($r1, $r2)"
[ "$(cat "$tmp/two.gto.check")" = mine ] && ok "a user's OUT.gto.check is left alone" || ko "a user's OUT.gto.check is left alone"
[ -z "$(ls "$tmp" | grep -F '.tmp.')" ] && ok "no temporary left" || ko "no temporary left"

# --scan's visible fraction (precompute/scan.c) against closed forms: of point pairs drawn
# by area, those on different faces of a closed cube all see each other (5/6), those on
# the two facing squares (1/2); 65,536 pairs: a standard deviation of 0.002. Its exchange
# fraction (element pairs drawn by element that face each other): the cube's 96 elements
# face all but the 15 others of their own face (80/95), the squares' 18 the 9 of the other
# square (9/17).
vis() { "$gen" "$1" --res "$2" -o "$tmp/vis.gltf" >/dev/null 2>&1 &&
        "$bake" --scan "$tmp/vis.gltf" --json 2>/dev/null | tr -d '\n ' | grep -o '"'"$3"'":[0-9.]*' | cut -d: -f2; }
fc=$(vis furnace 4 visible_fraction); ff=$(vis facing 3 visible_fraction)
xc=$(vis furnace 4 exchange_fraction); xf=$(vis facing 3 exchange_fraction)
awk -v f="$fc" 'BEGIN { exit !(f != "" && f > 5 / 6 - 0.01 && f < 5 / 6 + 0.01) }' &&
    ok "--scan: a closed cube's visible fraction $fc (5/6)" || ko "--scan: a closed cube's visible fraction ${fc:-?} (5/6)"
awk -v f="$ff" 'BEGIN { exit !(f != "" && f > 0.49 && f < 0.51) }' &&
    ok "--scan: two facing squares' visible fraction $ff (1/2)" || ko "--scan: two facing squares' visible fraction ${ff:-?} (1/2)"
awk -v f="$xc" 'BEGIN { exit !(f != "" && f > 80 / 95 - 0.01 && f < 80 / 95 + 0.01) }' &&
    ok "--scan: a closed cube's exchange fraction $xc (80/95)" || ko "--scan: a closed cube's exchange fraction ${xc:-?} (80/95)"
awk -v f="$xf" 'BEGIN { exit !(f != "" && f > 9 / 17 - 0.01 && f < 9 / 17 + 0.01) }' &&
    ok "--scan: two facing squares' exchange fraction $xf (9/17)" || ko "--scan: two facing squares' exchange fraction ${xf:-?} (9/17)"
# --scan's estimate is an upper bound fitted to measured bakes (docs/triangles.md "--scan's
# estimate, refitted (session 8)"): for a triangle scene at quality 3 the peak the kernel
# then measures and the file's bytes lie under it, and within the fit's band of it (2
# threads, as the fit): the plain bake's peak 1.62x, its bytes 1.95x (this bake 1.24x
# and 1.74x when fitted). The bake's own memory estimate (--json memory_mb.estimated,
# what --max-memory is checked against) lies over the peak too, within 1.3x (1.10x to
# 1.17x measured; it was 0.71x before session 8 counted the balance and the streamed sum).
if "$bake" --scan assets/test/cornell_shapes.gltf -q 3 --json >"$tmp/cs.scan" 2>"$tmp/err" &&
   "$bake" assets/test/cornell_shapes.gltf -q 3 --threads 2 -o "$tmp/cs.gto" --json --quiet >"$tmp/cs.json" 2>"$tmp/err"; then
    tr -d '\n ' <"$tmp/cs.scan" | grep -o '"estimate":{[^}]*}' >"$tmp/cs.est"
    se=$(jnum memory_mb "$tmp/cs.est"); sb=$(jnum bytes "$tmp/cs.est"); peak=$(jnum peak_rss "$tmp/cs.json"); bytes=$(stat -c %s "$tmp/cs.gto")
    own=$(jnum estimated "$tmp/cs.json")
    # over_within WHAT ESTIMATE MEASURED FACTOR: the estimate at or over the measured, within the factor
    over_within() {
        awk -v e="$2" -v m="$3" -v f="$4" 'BEGIN { exit !(m > 0 && e >= m && e <= f * m) }' &&
            ok "$1 $2 over the $3 measured, within $4x" || ko "$1 $2 over the $3 measured, within $4x"
    }
    if [ "$asan" = 1 ]; then
        skipped "--scan: peak estimate $se MB against the peak (AddressSanitizer's own memory counts in it)"
        skipped "memory: the bake's estimate $own MB against the peak (AddressSanitizer's own memory counts in it)"
    else
        over_within "--scan: peak estimate (MB)" "$se" "$peak" 1.65
        over_within "memory: the bake's own estimate of its peak (MB)" "$own" "$peak" 1.3
    fi
    over_within "--scan: file estimate (bytes)" "$sb" "$bytes" 2
else
    ko "cornell_shapes --scan and bake"
fi

# With --clusters (T never formed, the products E1 (U P)) the estimate covers the peak
# too: on the atrium at detail 0.25 (4 s of CPU) it lay under it (111 MB against 124)
# before the products' checks counted U P and the sum's growth (docs/clusters.md "The
# memory estimate with T never formed"); now 186 against 111 (the process's baseline,
# about 35 MB, is in both), so within 2x. A budget under the peak is refused (exit 7,
# nothing written; under a small budget the products' estimates sample every 16th column
# and come out lower, 150 MB at a budget of 166, so the figure is not the one to halve);
# one above the estimate is enough.
if "$gen" atrium --detail 0.25 -o "$tmp/at.gltf" >/dev/null 2>"$tmp/err" &&
   "$bake" "$tmp/at.gltf" -q 1 --clusters -o "$tmp/at.gto" --json --quiet >"$tmp/at.json" 2>"$tmp/err"; then
    peak=$(jnum peak_rss "$tmp/at.json"); est=$(jnum estimated "$tmp/at.json")
    if [ "$asan" = 1 ]; then
        skipped "memory: --clusters estimate $est MB against the peak (AddressSanitizer's own memory counts in it)"
    else
        awk -v p="$peak" -v e="$est" 'BEGIN { exit !(p > 10 && e >= p && e <= 2 * p) }' &&
            ok "memory: --clusters estimate $est MB covers the peak $peak MB, within 2x" ||
            ko "memory: --clusters estimate $est MB covers the peak $peak MB, within 2x"
    fi
    low=$(awk -v p="$peak" 'BEGIN { printf "%d", p * 0.9 }')
    expect_exit "memory: --clusters budget $low MB refused: exit 7" 7 "would need about [0-9]+ MB.*budget of $low MB" \
        "$bake" "$tmp/at.gltf" -q 1 --clusters -o "$tmp/atlow.gto" --max-memory "$low" --quiet
    [ ! -e "$tmp/atlow.gto" ] && ok "memory: --clusters, nothing written when refused" ||
        ko "memory: --clusters, nothing written when refused"
    # --scan --clusters at quality 1: over the peak and the bytes (its model was fitted on
    # quality 3 and 5 alone until session 13 and lay 7x under the 22,224 atrium's CPU and
    # 5.5x under its peak while calling itself an upper bound; docs/triangles.md)
    if "$bake" --scan "$tmp/at.gltf" -q 1 --clusters --json >"$tmp/at.scan" 2>"$tmp/err"; then
        tr -d '\n ' <"$tmp/at.scan" | grep -o '"estimate":{[^}]*}' >"$tmp/at.est"
        sp=$(jnum memory_mb "$tmp/at.est"); sb=$(jnum bytes "$tmp/at.est"); ab=$(stat -c %s "$tmp/at.gto")
        [ "$asan" = 1 ] || awk -v e="$sp" -v m="$peak" 'BEGIN { exit !(m > 0 && e >= m && e <= 3 * m) }' &&
            ok "--scan --clusters -q 1: peak estimate $sp MB over the peak $peak MB, within 3x" ||
            ko "--scan --clusters -q 1: peak estimate $sp MB over the peak $peak MB, within 3x"
        awk -v e="$sb" -v m="$ab" 'BEGIN { exit !(m > 0 && e >= m && e <= 3 * m) }' &&
            ok "--scan --clusters -q 1: file estimate $sb over the $ab bytes, within 3x" ||
            ko "--scan --clusters -q 1: file estimate $sb over the $ab bytes, within 3x"
    else
        ko "--scan --clusters -q 1 of the atrium"
    fi
    enough=$(awk -v e="$est" 'BEGIN { printf "%d", e * 1.1 + 16 }')
    check "memory: --clusters budget $enough MB is enough" "$bake" "$tmp/at.gltf" -q 1 --clusters \
        -o "$tmp/atok.gto" --max-memory "$enough" --quiet
    # Before a bake, on a terminal: the estimate at the bake's own options and budget; for a
    # diffuse scene whose plain estimate passes the budget, what --clusters would cost; then
    # the bake stops at the first stage over the budget (main.c, scan.c
    # wrt_scan_print_bake_hint). At 1,060 elements the plain quality-5 model says 4 GB.
    if "$gen" atrium --detail 0.5 -o "$tmp/at5.gltf" >/dev/null 2>"$tmp/err"; then
        "$bake" "$tmp/at5.gltf" -o "$tmp/at5.gto" --progress --max-memory 100 >/dev/null 2>"$tmp/hint.err"; rc=$?
        grep -q '^wrt-bake: estimate at quality 5: at most about .* of CPU, [0-9]* MB peak, [0-9]* MB file .*the budget 100 MB' "$tmp/hint.err" &&
            grep -q '^wrt-bake: hint: 1060 diffuse elements bake faster with --clusters: .* at quality 5, .* at -q 1' "$tmp/hint.err" &&
            grep -q 'the estimate passes the budget' "$tmp/hint.err" && [ "$rc" = 7 ] && [ ! -e "$tmp/at5.gto" ] &&
            ok "a large plain bake over its budget: the estimate, the --clusters hint, exit 7, nothing written" ||
            ko "a large plain bake over its budget: the estimate and hint (exit $rc: $(grep wrt-bake "$tmp/hint.err" | head -3))"
        "$bake" "$tmp/at.gltf" -q 1 --clusters -o "$tmp/atq.gto" --progress >/dev/null 2>"$tmp/hint2.err"
        "$bake" "$tmp/at.gltf" -q 1 --clusters -o "$tmp/atq.gto" --quiet >/dev/null 2>"$tmp/hint3.err"
        grep -q '^wrt-bake: estimate at quality 1 with --clusters:' "$tmp/hint2.err" && ! grep -q 'hint:\|passes the budget' "$tmp/hint2.err" &&
            ! grep -q 'estimate' "$tmp/hint3.err" &&
            ok "--clusters within its budget: the estimate line alone; --quiet: none" ||
            ko "--clusters within its budget: the estimate line alone; --quiet: none ($(cat "$tmp/hint2.err" "$tmp/hint3.err" | grep wrt-bake | head -3))"
    else
        ko "atrium --detail 0.5 for the estimate's hint"; show_err
    fi
    # wrt-bake's own choice of the cluster hierarchy (main.c choose_clusters, scan.c
    # wrt_scan_clusters_auto): without --clusters or --no-clusters, a diffuse scene with 1M
    # ordered pairs of elements in sight of each other (or 10,000 elements) is baked with
    # --clusters, byte for byte; a glossy one, a maze whose walls hide most pairs and a
    # smaller box are not. Cornell at --res 12: 2,160 elements, 46% of pairs in sight (2.15M).
    chosen() { "$bake" --scan "$@" --json 2>"$tmp/err" | tr -d '\n' | grep -o '"clusters_chosen":"[a-z]*"' | cut -d'"' -f4; }
    if "$gen" cornell --res 12 -o "$tmp/c12.gltf" >/dev/null 2>"$tmp/err" &&
       "$gen" cornell-glossy --res 12 -o "$tmp/cg12.gltf" >/dev/null 2>>"$tmp/err" &&
       "$gen" cornell --res 8 -o "$tmp/c8.gltf" >/dev/null 2>>"$tmp/err" &&
       "$gen" maze --cells 16 -o "$tmp/m16.gltf" >/dev/null 2>>"$tmp/err"; then
        a=$(chosen "$tmp/c12.gltf"); b=$(chosen "$tmp/c12.gltf" --no-clusters); c=$(chosen "$tmp/c12.gltf" --clusters)
        d=$(chosen "$tmp/cg12.gltf"); e=$(chosen "$tmp/c8.gltf"); m=$(chosen "$tmp/m16.gltf")
        [ "$a/$b/$c/$d/$e/$m" = auto/none/given/none/none/none ] &&
            "$bake" --scan "$tmp/c12.gltf" --json | grep -q '"model":"clusters:' &&
            "$bake" --scan "$tmp/c12.gltf" --no-clusters --json | grep -q '"model":"plain:' &&
            "$bake" --scan "$tmp/c12.gltf" | grep -q '^clusters: 2160 diffuse elements, 2.[0-9]M of their ordered pairs in sight' &&
            ok "--scan: the cluster hierarchy taken by itself for 2,160 diffuse elements in sight; not glossy, 960 elements, a 2,245-element maze, --no-clusters" ||
            ko "--scan: the cluster hierarchy by itself: c12 $a, --no-clusters $b, --clusters $c, glossy $d, res 8 $e, maze 16 $m"
        "$bake" "$tmp/c12.gltf" -q 1 -o "$tmp/c12auto.gto" --json --progress >"$tmp/c12.json" 2>"$tmp/c12.err"; ra=$?
        "$bake" "$tmp/c12.gltf" -q 1 --clusters -o "$tmp/c12cl.gto" --quiet >/dev/null 2>"$tmp/err"; rb=$?
        [ "$ra/$rb" = 0/0 ] && cmp -s "$tmp/c12auto.gto" "$tmp/c12cl.gto" && grep -q '"clusters_chosen":"auto"' "$tmp/c12.json" &&
            grep -q '"clusters":{"links":[1-9]' "$tmp/c12.json" &&
            grep -q '^wrt-bake: 2160 diffuse elements, 2.[0-9]M of their ordered pairs in sight: baked with --clusters' "$tmp/c12.err" &&
            ok "a bake without --clusters of 2,160 diffuse elements in sight: said, and --clusters' file byte for byte" ||
            ko "a bake without --clusters of 2,160 diffuse elements in sight (exit $ra, $rb; $(grep wrt-bake "$tmp/c12.err" | head -2))"
        expect_exit "--no-clusters with --clusters: usage error" 1 "--no-clusters with --clusters or a --cluster option" \
            "$bake" "$tmp/c12.gltf" -o "$tmp/c12x.gto" --no-clusters --cluster-eps 1e-3
        [ ! -e "$tmp/c12x.gto" ] && ok || ko "--no-clusters with --cluster-eps wrote a file"
    else
        ko "cornell --res 12, cornell-glossy --res 12, cornell --res 8, maze --cells 16"; show_err
    fi
    # The series by blocks of columns (series_cols.c): a column's entries do not depend on
    # the blocks, so one block gives the default 16's bytes; with the bounces fixed and no
    # tail (what the blocks decide from the power iteration alone), the terms held whole
    # give the same operator (every key, row and value bit; the files differ in the
    # provenance and the light-left figure)
    if "$bake" "$tmp/at.gltf" -q 1 --clusters --series-columns 1 -o "$tmp/at1.gto" --quiet 2>"$tmp/err"; then
        cmp -s "$tmp/at.gto" "$tmp/at1.gto" && ok "--series-columns 1 and the default 16: the same bytes" ||
            ko "--series-columns 1 and the default 16: the files differ"
    else
        ko "--series-columns 1 bake"; show_err
    fi
    if "$bake" "$tmp/at.gltf" -q 1 --clusters --max-bounces 3 --no-tail -o "$tmp/atb.gto" --quiet 2>"$tmp/err" &&
       "$bake" "$tmp/at.gltf" -q 1 --clusters --max-bounces 3 --no-tail --series-columns 0 -o "$tmp/atw.gto" \
           --quiet 2>>"$tmp/err"; then
        same=$("$build/tools/gto_same" "$tmp/atb.gto" "$tmp/atw.gto" 2>&1)
        [[ "$same" == *"the same operator"* ]] && ok "series by blocks against the terms whole, 3 bounces: $same" ||
            ko "series by blocks against the terms whole, 3 bounces: $same"
    else
        ko "--max-bounces 3 --no-tail bakes by blocks and whole"; show_err
    fi
else
    ko "atrium --clusters bake"
fi

# Memory: a glossy bake reports its peak resident memory and the largest need it
# estimated before allocating; the estimate covers the peak the bake then had (measured
# by the kernel, not by the bake's own accounting) and is at most 1.5x that peak, a budget under that peak is refused
# (exit 7) with the estimated figure named and nothing written, a budget at the
# estimate is enough.
if "$gen" cornell-glossy --roughness 0.3 -o "$tmp/cg.gltf" >/dev/null 2>"$tmp/err" &&
   "$bake" "$tmp/cg.gltf" -q 3 -o "$tmp/cg.gto" --json --quiet >"$tmp/cg.json" 2>"$tmp/err"; then
    peak=$(jnum peak_rss "$tmp/cg.json"); est=$(jnum estimated "$tmp/cg.json")
    # honest both ways (issue 22: it was 5x to 16x the peak when it counted upper bounds)
    if awk -v p="$peak" -v e="$est" 'BEGIN { exit !(p > 10 && e >= 0.9 * p && e <= 1.5 * p) }'; then
        ok "memory: estimate $est MB covers the peak $peak MB, within 2.5x"
    else
        ko "memory: estimate $est MB covers the peak $peak MB, within 2.5x"
    fi
    low=$(awk -v p="$peak" 'BEGIN { printf "%d", p / 2 }')
    expect_exit "memory: budget $low MB refused: exit 7, figure named" 7 "would need (about|at least) [0-9]+ MB.*budget of $low MB" \
        "$bake" "$tmp/cg.gltf" -q 3 -o "$tmp/cglow.gto" --max-memory "$low" --quiet
    [ ! -e "$tmp/cglow.gto" ] && [ -z "$(ls "$tmp" | grep -F '.tmp.')" ] && ok "memory: nothing written when refused" ||
        ko "memory: nothing written when refused"
    # Under the columns' upper bound the series samples every 16th column of each
    # product instead: that estimate must still cover the peak, and fit 1.3 x the peak.
    tight=$(awk -v p="$peak" 'BEGIN { printf "%d", p * 1.3 + 1 }')
    if "$bake" "$tmp/cg.gltf" -q 3 -o "$tmp/cgt.gto" --max-memory "$tight" --json --quiet >"$tmp/cgt.json" 2>"$tmp/err"; then
        p2=$(jnum peak_rss "$tmp/cgt.json"); e2=$(jnum estimated "$tmp/cgt.json")
        awk -v p="$p2" -v e="$e2" 'BEGIN { exit !(e >= 0.95 * p && e <= 1.5 * p) }' &&
            ok "memory: sampled estimate $e2 MB covers the peak $p2 MB, within 2.5x" ||
            ko "memory: sampled estimate $e2 MB covers the peak $p2 MB, within 2.5x"
    else
        ko "memory: a budget of $tight MB (1.3 x the peak) is enough"
    fi
    # A setting far beyond the budget (the glossy asset at quality 9, 64 x 64 angular
    # cells on every glossy link) is refused before its link tables grow past the
    # budget: the kernel's peak for the process (getrusage of the child) stays under it.
    rc=$(python3 -c 'import resource, subprocess, sys
p = subprocess.run(sys.argv[1:-1], stdout=subprocess.DEVNULL, stderr=open(sys.argv[-1] + ".err", "w"))
print(p.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss // 1024)' \
        "$bake" assets/glossy.gltf -q 9 -o "$tmp/g9.gto" --max-memory 400 --quiet "$tmp/g9")
    set -- $rc
    # AddressSanitizer's shadow memory and quarantine count in the process's peak, so
    # under config=sanitize the refusal is checked but not the peak.
    if [ "$asan" = 1 ] && [ "${1:-x}" = 7 ] && grep -q "budget of 400 MB" "$tmp/g9.err" && [ ! -e "$tmp/g9.gto" ]; then
        ok "memory: quality 9 glossy refused at 400 MB (exit 7)"
        skipped "memory: its peak under 400 MB (${2:-?} MB with AddressSanitizer's own memory)"
    elif [ "${1:-x}" = 7 ] && [ "${2:-999999}" -le 400 ] && grep -q "budget of 400 MB" "$tmp/g9.err" && [ ! -e "$tmp/g9.gto" ]; then
        ok "memory: quality 9 glossy refused at 400 MB (exit 7), peak ${2} MB"
    else
        ko "memory: quality 9 glossy refused at 400 MB (exit ${1:-?}), peak ${2:-?} MB"
    fi
    enough=$(awk -v e="$est" 'BEGIN { printf "%d", e * 1.1 + 16 }')
    check "memory: budget $enough MB is enough" "$bake" "$tmp/cg.gltf" -q 3 -o "$tmp/cgok.gto" --max-memory "$enough" --quiet
else
    ko "cornell-glossy bake"
fi

# An interrupted bake leaves nothing behind and exits 4.
"$bake" "$tmp/maze.gltf" -o "$tmp/int.gto" --quality 6 --quiet >/dev/null 2>&1 &
pid=$!
# once its handler is installed (SIGTERM, bit 15 of /proc's SigCgt; at most 30 s: a loaded
# machine can take more than a second to load the shared libraries), then half a second on
for _ in $(seq 300); do
    cgt=$(awk '/^SigCgt:/ {print $2}' /proc/$pid/status 2>/dev/null)
    [ -n "$cgt" ] && [ $(( 0x$cgt >> 14 & 1 )) -eq 1 ] && break
    sleep 0.1
done
sleep 0.5
kill -TERM $pid 2>/dev/null  # (background jobs of a script ignore SIGINT)
wait $pid; rc=$?
if [ $rc -eq 4 ] && [ ! -e "$tmp/int.gto" ] && [ -z "$(ls "$tmp" | grep -F '.tmp.')" ]; then
    ok "interrupted bake: no output, no temporary (exit $rc)"
else
    ko "interrupted bake: no output, no temporary (exit $rc)"
fi

# One set of phases (issue 26.5): the progress lines (forced with --progress), the text
# summary and --json name the same phases, in the same order, and give the same seconds
# (within 0.1 s + 10%: the progress line is drawn a moment after its phase ends).
"$bake" assets/cornell.gltf -o "$tmp/ph.gto" --quality 2 --progress > "$tmp/ph.txt" 2> "$tmp/ph.err"
prog=$(tr '\r' '\n' < "$tmp/ph.err" | grep ' done' | awk '{print $1 "=" $(NF-2)}' | tr '\n' ' ')
summ=$(grep '^  time ' "$tmp/ph.txt" | sed -E 's/^  time +//; s/, total.*//; s/ ([0-9.]+) s/=\1/g; s/,//g')
if [ "$(echo "$prog" | sed -E 's/=[0-9.]+//g; s/ +$//')" = "$(echo "$summ" | sed -E 's/=[0-9.]+//g')" ] &&
   awk -v p="$prog" -v s="$summ" 'BEGIN { n = split(p, a, " "); split(s, b, " "); bad = 0
        for (i = 1; i <= n; i++) { split(a[i], x, "="); split(b[i], y, "="); d = x[2] - y[2]; if (d < 0) d = -d
            if (d > 0.1 + 0.1 * y[2]) bad = 1 }
        exit bad }'; then
    ok "progress phases = summary phases, same seconds (progress: $prog; summary: $summ)"
else
    ko "progress phases = summary phases, same seconds (progress: $prog; summary: $summ)"
fi
"$bake" assets/cornell.gltf -o "$tmp/ph.gto" --quality 2 --json > "$tmp/ph.json" 2>/dev/null
jq -e '.seconds | (keys_unsorted[0:5] == ["load", "dto", "balance", "series", "gto"]) and .gto == .series and
       (.load + .dto + .balance + .series + .write <= .total + 1e-3)' "$tmp/ph.json" >/dev/null &&
    ok "--json: seconds of the same phases, their sum within the total" ||
    ko "--json: seconds of the same phases ($(jq -c .seconds "$tmp/ph.json"))"
grep -q 'the scene is open: light leaves it (a ray from quad [0-9]*, mesh "' "$tmp/ph.txt" &&
    ok "an open scene says where light leaves it" || ko "an open scene says where light leaves it: $(grep balance "$tmp/ph.txt")"

# Huge pages (precompute/main.c huge_pages_restart): where the kernel gives them on request
# ("madvise"), wrt-bake starts itself again with glibc's allocator asking for them, unless
# WRT_HUGE_PAGES=0 or GLIBC_TUNABLES names the tunable; --json says which; the same bytes.
thp=$(grep -o '\[[a-z]*\]' /sys/kernel/mm/transparent_hugepage/enabled 2>/dev/null)
if "$bake" assets/cornell.gltf -q 2 -o "$tmp/hp1.gto" --json --quiet >"$tmp/hp1.json" 2>/dev/null &&
   WRT_HUGE_PAGES=0 "$bake" assets/cornell.gltf -q 2 -o "$tmp/hp0.gto" --json --quiet >"$tmp/hp0.json" 2>/dev/null &&
   GLIBC_TUNABLES=glibc.malloc.hugetlb=0 "$bake" assets/cornell.gltf -q 2 -o "$tmp/hpt.gto" --json --quiet >"$tmp/hpt.json" 2>/dev/null; then
    h="$(jq -r .memory_mb.huge_pages "$tmp/hp1.json") $(jq -r .memory_mb.huge_pages "$tmp/hp0.json") $(jq -r .memory_mb.huge_pages "$tmp/hpt.json")"
    case "$thp" in
        "[madvise]") want="true false false" ;;
        "[always]") want="true true true" ;;
        *) want="false false false" ;;
    esac
    [ "$h" = "$want" ] && ok "huge pages (kernel ${thp:-none}): default, WRT_HUGE_PAGES=0, hugetlb=0: $h" ||
        ko "huge pages (kernel ${thp:-none}): $h, wanted $want"
    cmp -s "$tmp/hp1.gto" "$tmp/hp0.gto" && cmp -s "$tmp/hp1.gto" "$tmp/hpt.gto" &&
        ok "the same bytes with and without huge pages" || ko "bytes differ with and without huge pages"
else
    ko "bakes with and without huge pages"
fi

summary
