#!/usr/bin/env bash
# tools/link-static-lib.sh OUT.a HEADER OBJECTS...: libwrt.a as one object. The objects
# (compiled with -fvisibility=hidden -ffunction-sections -fdata-sections) are partially
# linked with the header's API functions (tools/api-symbols.sh) as the roots of
# --gc-sections, so that what the API cannot reach (the .gto writer, the aborting
# wrt_xmalloc) is dropped; every hidden symbol is then made local, and the undefined
# symbols that only the dropped code named (abort, the writer's file calls) are removed
# from the symbol table. What is left exports the API alone and names nothing it does
# not call (tests/exports.sh checks it with nm).
set -euo pipefail
out=$1 header=$2
shift 2
tmp=$out.o
roots=()
for s in $(bash "$(dirname "$0")/api-symbols.sh" "$header"); do roots+=(-u "$s"); done
ld -r --gc-sections "${roots[@]}" "$@" -o "$tmp"
objcopy --localize-hidden "$tmp"
# undefined symbols no relocation names any more
mapfile -t unused < <(comm -23 <(nm -u "$tmp" | awk '{print $2}' | sort -u) \
    <(objdump -r "$tmp" | awk 'NF >= 3 && $1 ~ /^[0-9a-f]+$/ {sub(/[-+]0x[0-9a-f]+$/, "", $3); print $3}' | sort -u))
strip_args=()
for s in "${unused[@]}"; do strip_args+=(--strip-symbol="$s"); done
[ ${#strip_args[@]} -eq 0 ] || objcopy "${strip_args[@]}" "$tmp"
rm -f "$out"
ar rcs "$out" "$tmp"
rm -f "$tmp"
