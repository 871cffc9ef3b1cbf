#!/usr/bin/env bash
# tests/install.sh BUILD: the runtime library as an embedder gets it. `make install` into a
# temporary PREFIX; the installed libwrt.so needs no OpenGL; examples/relight.c copied out
# of the tree and built against the installed copy alone with pkg-config --static; run on
# a scene it has never seen (a maze of 3 x 3 corridors, seed 7, generated and baked here):
# one line per quad, every value finite, some light reaches some quad, and the same
# numbers as the in-tree build of the example. Prints "N passed, N failed".
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
summary
