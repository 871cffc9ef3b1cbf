#!/usr/bin/env bash
# tests/install.sh BUILD: the runtime library as an embedder gets it. `make install` into a
# temporary PREFIX; the installed libwrt.so needs no OpenGL; examples/relight.c copied out
# of the tree and built against the installed copy alone with pkg-config --static (no
# libwrt.so NEEDED) and without (libwrt.so.1 NEEDED); the header's example, extracted
# from between its markers, compiled and run the same way; run on
# a scene it has never seen (a maze of 3 x 3 corridors, seed 7, generated and baked here):
# one line per quad, every value finite, some light reaches some quad, and the same
# numbers as the in-tree build of the example. Then examples/engine.c, built the same way
# outside the tree, on a bake of tests/data/blender_room.gltf (Blender's export, with
# TEXCOORD_0 and doubleSided twins): its quad-to-source map agrees with the glTF
# (tests/srcmap_check.py reads the glTF itself), its PFM atlas has every quad's block
# inside, apart, with a border that repeats the edge texels, and the cell-average
# atlases of two lights add up to the pair's within 1e-5 of the peak. Prints "N passed,
# N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
root=$PWD
. tests/lib.sh install.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
make --no-print-directory -s install PREFIX="$tmp/prefix" BUILD="$build" >"$tmp/install.log" 2>&1
check_status "make install" $?
for f in include/wrt.h lib/libwrt.a lib/libwrt.so lib/pkgconfig/wrt.pc; do
    [ -e "$tmp/prefix/$f" ]; check_status "installed $f" $?
done
! ldd "$tmp/prefix/lib/libwrt.so" | grep -qiE 'libGL|libEGL|glfw|OpenImageIO'
check_status "libwrt.so needs no OpenGL, EGL, GLFW or OpenImageIO" $?
mkdir -p "$tmp/out" && cp examples/relight.c "$tmp/out/ex.c"
# A library built with config=sanitize needs its sanitizers' runtime in the program too.
san=""; nm "$build/libwrt.a" 2>/dev/null | grep -q __asan && san="-fsanitize=address,undefined"
(cd "$tmp/out" && PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" \
    cc -std=c11 $san ex.c $(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --cflags --libs --static wrt) -o ex) \
    >"$tmp/cc.log" 2>&1
check_status "example builds outside the tree against the installed copy" $?
[ $fail -eq 0 ] || cat "$tmp/cc.log" "$tmp/install.log"
# --static is a static link of libwrt: libwrt.so not NEEDED; without it, the shared one
! readelf -d "$tmp/out/ex" 2>/dev/null | grep NEEDED | grep -q 'libwrt\.so'
check_status "pkg-config --static: libwrt.so not NEEDED ($(readelf -d "$tmp/out/ex" 2>/dev/null | grep -c NEEDED) NEEDED entries)" $?
(cd "$tmp/out" && cc -std=c11 $san ex.c $(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --cflags --libs wrt) \
    -o ex_so) >"$tmp/cc_so.log" 2>&1 && readelf -d "$tmp/out/ex_so" | grep NEEDED | grep -q 'libwrt\.so\.1'
check_status "pkg-config without --static: linked with libwrt.so.1" $?
# the header's example, between its markers, compiled against the installed copy
sed -n '/WRT_EXAMPLE_BEGIN/,/WRT_EXAMPLE_END/{/WRT_EXAMPLE_/d;p}' "$tmp/prefix/include/wrt.h" |
    sed -E 's/^ \*( {0,3})//' >"$tmp/out/hdr.c"
[ "$(grep -c main "$tmp/out/hdr.c")" -ge 1 ]; check_status "the header's example extracted ($(wc -l <"$tmp/out/hdr.c") lines)" $?
(cd "$tmp/out" && cc -std=c11 -Wall -Wextra -Werror $san hdr.c \
    $(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --cflags --libs --static wrt) -o hdr) >"$tmp/hdr.log" 2>&1
check_status "the header's example compiles (-Wall -Wextra -Werror, static): $(head -c 300 "$tmp/hdr.log")" $?
"$build/wrt-scenegen" maze --cells 3 --seed 7 --out "$tmp/m.gltf" >/dev/null 2>&1 &&
    "$build/wrt-bake" "$tmp/m.gltf" -o "$tmp/m.gto" -q 2 --quiet >/dev/null 2>&1
check_status "bake a fresh scene" $?
"$tmp/out/ex" "$tmp/m.gto" >"$tmp/ex.txt" 2>"$tmp/ex.err"
check_status "example runs (exit 0)" $?
nq=$("$build/wrt-bake" --info "$tmp/m.gto" 2>/dev/null | awk '$1 == "quads" {print $4; exit}')
lines=$(wc -l <"$tmp/ex.txt")
[ -n "$nq" ] && [ "$lines" -eq "$nq" ]; check_status "one line per quad ($lines lines, $nq quads)" $?
awk '{for (i = 2; i <= 4; i++) if ($i != $i + 0 || $i < 0) bad = 1; if ($2 + $3 + $4 > 0) lit++}
     END {exit !(NR > 0 && !bad && lit > 0)}' "$tmp/ex.txt"
check_status "finite, non-negative, some quad lit" $?
"$build/examples/relight" "$tmp/m.gto" >"$tmp/ex2.txt" 2>/dev/null && cmp -s "$tmp/ex.txt" "$tmp/ex2.txt"
check_status "installed and in-tree builds print the same numbers" $?
"$tmp/out/ex_so" "$tmp/m.gto" >"$tmp/ex3.txt" 2>/dev/null && cmp -s "$tmp/ex.txt" "$tmp/ex3.txt"
check_status "the shared library prints the same numbers" $?
"$tmp/out/hdr" "$tmp/m.gto" >"$tmp/hdr.txt" 2>"$tmp/hdr.err"
hl=$(grep -c '^quad [0-9]*: mesh [0-9]*, [0-9]* x [0-9]* texels' "$tmp/hdr.txt")
[ -n "$nq" ] && [ "$hl" -eq "$nq" ]; check_status "the header's example runs: a line per quad ($hl of $nq)" $?
# examples/engine.c: an engine's use, from the installed header and library alone
cp examples/engine.c "$tmp/out/engine.c"
(cd "$tmp/out" && cc -std=c11 -Wall -Wextra -Werror $san engine.c \
    $(PKG_CONFIG_PATH="$tmp/prefix/lib/pkgconfig" pkg-config --cflags --libs --static wrt) -lm -o engine) \
    >"$tmp/engine_cc.log" 2>&1
check_status "examples/engine.c builds outside the tree (-Wall -Wextra -Werror, static): $(head -c 300 "$tmp/engine_cc.log")" $?
"$build/wrt-bake" tests/data/blender_room.gltf -o "$tmp/room.gto" -q 2 --quiet >/dev/null 2>&1
check_status "bake tests/data/blender_room.gltf" $?
"$tmp/out/engine" "$tmp/room.gto" "$tmp/room.pfm" >"$tmp/engine.txt" 2>"$tmp/engine.err"
check_status "engine runs: cell averages superpose: $(grep 'superposition cells' "$tmp/engine.txt")" $?
grep 'superposition smooth' "$tmp/engine.txt"
m=$(python3 tests/srcmap_check.py tests/data/blender_room.gltf "$tmp/engine.txt")
check_status "the quad-to-source map agrees with the glTF: $m" $?
python3 - "$tmp/room.pfm" "$tmp/engine.txt" <<'PY'
import struct, sys
d = open(sys.argv[1], "rb").read()
head = d.split(b"\n", 3)
w, h = map(int, head[1].split()); assert head[2] == b"-1.0"
px = struct.unpack("<%df" % (w * h * 3), head[3][:w * h * 12])
rows = [px[(h - 1 - y) * w * 3:(h - y) * w * 3] for y in range(h)]  # PFM: bottom row first
at = lambda x, y: rows[y][3 * x:3 * x + 3]
rects = [tuple(int(v) for v in l.split()[20:23]) for l in open(sys.argv[2]) if l.startswith("quad ")]
used, bad, lit = set(), [], 0
for q, (x, y, r) in enumerate(rects):
    if x < 1 or y < 1 or x + r + 1 > w or y + r + 1 > h: bad.append("quad %d outside" % q); continue
    tile = {(i, j) for i in range(x - 1, x + r + 1) for j in range(y - 1, y + r + 1)}
    if tile & used: bad.append("quad %d overlaps" % q)
    used |= tile
    cl = lambda v: min(max(v, 0), r - 1)
    for i in range(-1, r + 1):
        for j in range(-1, r + 1):
            if at(x + i, y + j) != at(x + cl(i), y + cl(j)): bad.append("quad %d border (%d, %d)" % (q, i, j))
    lit += any(c > 0 for i in range(r) for j in range(r) for c in at(x + i, y + j))
print("atlas %d x %d, %d quads, %d lit, %s" % (w, h, len(rects), lit, "; ".join(bad[:3]) or "blocks inside, apart, borders repeat the edges"))
sys.exit(1 if bad or lit == 0 or len(rects) != 88 else 0)
PY
check_status "the PFM atlas: 88 blocks inside and apart, borders replicate edges, light in it" $?
# a triangle that pairs with nothing: three quads, parts 0..2 of triangle 0 (no light
# reaches a lone triangle, so the engine's own superposition verdict is not asked for)
"$build/wrt-bake" tests/data/bad_unpaired.gltf -o "$tmp/tri.gto" -q 2 --quiet >/dev/null 2>&1 &&
    { "$tmp/out/engine" "$tmp/tri.gto" "$tmp/tri.pfm" >"$tmp/tri.txt" 2>&1; [ "$(grep -c 'kind triangle part' "$tmp/tri.txt")" -eq 3 ]; }
check_status "a lone triangle: three quads of kind triangle" $?
m=$(python3 tests/srcmap_check.py tests/data/bad_unpaired.gltf "$tmp/tri.txt")
check_status "its map agrees with the glTF: $m" $?
summary
