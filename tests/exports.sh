#!/usr/bin/env bash
# tests/exports.sh BUILD: libwrt exports its documented API and nothing else, and names
# nothing that ends the process. The API is every function declared with WRT_API in
# include/wrt.h (read here with grep, not with the build's own tools/api-symbols.sh);
# libwrt.so's dynamic symbols (nm -D --defined-only) and libwrt.a's global symbols must be
# exactly that list, and neither may refer to abort, exit and their kin, assert's
# failure handler or wrt's aborting allocators (wrt_xmalloc and co.).
# Prints "N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
. tests/lib.sh exports.sh
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# one name per declaration: the first wrt_ name followed by '(' on each WRT_API line
grep -E '^WRT_API ' include/wrt.h | while read -r line; do grep -oE 'wrt_[a-z0-9_]+\(' <<<"$line" | head -n 1; done |
    sed 's/($//' | sort -u >"$tmp/api"
n=$(wc -l <"$tmp/api")
[ "$n" -ge 20 ]; check_status "the header declares the API with WRT_API ($n functions)" $?
nm -D --defined-only "$build/libwrt.so" | awk '$2 ~ /^[TDBRVWi]$/ {sub(/@.*/, "", $3); print $3}' | sort -u >"$tmp/so"
diff "$tmp/api" "$tmp/so" >"$tmp/so.diff"
check_status "libwrt.so exports exactly the API ($(wc -l <"$tmp/so") symbols): $(tr '\n' ' ' <"$tmp/so.diff" | cut -c1-300)" $?
nm --defined-only "$build/libwrt.a" 2>/dev/null | awk 'NF == 3 && $2 ~ /^[A-Z]$/ {print $3}' | sort -u >"$tmp/a"
diff "$tmp/api" "$tmp/a" >"$tmp/a.diff"
check_status "libwrt.a's global symbols are exactly the API ($(wc -l <"$tmp/a") symbols): $(tr '\n' ' ' <"$tmp/a.diff" | cut -c1-300)" $?
bad='^(abort|exit|_exit|_Exit|quick_exit|__assert_fail|__assert_perror_fail|err|errx|verr|verrx|wrt_xmalloc|wrt_xcalloc|wrt_xrealloc)$'
so_bad=$(nm -D --undefined-only "$build/libwrt.so" | awk '{sub(/@.*/, "", $2); print $2}' | grep -E "$bad" | tr '\n' ' ')
[ -z "$so_bad" ]; check_status "libwrt.so refers to nothing that ends the process (${so_bad:-none})" $?
a_bad=$(nm -u "$build/libwrt.a" 2>/dev/null | awk '{print $2}' | grep -E "$bad" | tr '\n' ' ')
[ -z "$a_bad" ]; check_status "libwrt.a refers to nothing that ends the process (${a_bad:-none})" $?
# the check itself can fail: the objects the library is made of do name abort (wrt_xmalloc)
nm -u "$build"/obj/common/wrt_common.o 2>/dev/null | grep -qw abort
check_status "the check sees abort where it is (common/wrt_common.o's wrt_xmalloc)" $?
summary
