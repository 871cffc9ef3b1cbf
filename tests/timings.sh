#!/usr/bin/env bash
# timings.sh BUILD: the quick part of tools/readme_times.sh in `make test`: the README's
# "Timings" table parses, and its Cornell bake's CPU seconds are within a factor 2 of a
# bake measured now (`make timings` runs every row). Skipped in a sanitizer build, whose
# CPU times are not the release build's. Prints "timings: N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
if nm "$build/wrt-bake" 2>/dev/null | grep -q __asan_init; then
    echo "skipped timings: a sanitizer build's CPU times are not the README's"
    echo "timings: 0 passed, 0 failed, 1 skipped"
    exit 0
fi
ONLY=bake-cornell bash tools/readme_times.sh "$build"
