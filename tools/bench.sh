#!/usr/bin/env bash
# Bake benchmark: the paper's Table 1 for our assets. Bakes each scene at each quality
# RUNS times and prints the median times, link counts and file sizes as a markdown table.
# Usage: tools/bench.sh [BUILD] ; env SCENES="cornell maze glossy" QUALITIES="3 5 7" RUNS=3
# (default qualities 3 5 7, but 3 5 for glossy: at 7 its angular level 3 needs > 8 GB)
set -euo pipefail
build=${1:-build}
scenes=${SCENES:-"cornell maze glossy"}
qualities_for() {
    if [ -n "${QUALITIES:-}" ]; then echo "$QUALITIES"
    elif [ "$1" = glossy ]; then echo "3 5"
    else echo "3 5 7"; fi
}
runs=${RUNS:-3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
field() { grep -o "\"$1\":[0-9.e+-]*" "$2" | head -n 1 | cut -d: -f2; }
median() { sort -g | awk '{a[NR]=$1} END {if (NR % 2) print a[(NR+1)/2]; else print (a[NR/2]+a[NR/2+1])/2}'; }
echo "| scene | quality | t_DTO (s) | t_GTO (s) | total (s) | links DTO | links GTO | links gathered | entries stored | file (MB) | bounces |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for s in $scenes; do
    for q in $(qualities_for "$s"); do
        : > "$tmp/dto"; : > "$tmp/gto"; : > "$tmp/tot"
        for r in $(seq "$runs"); do
            "$build/wrt-bake" "assets/$s.gltf" -o "$tmp/out.gto" --quality "$q" --json --quiet --report-gathered > "$tmp/j"
            tr -d '\n' < "$tmp/j" | grep -o '"seconds":{[^}]*}' > "$tmp/sec"
            field dto "$tmp/sec" >> "$tmp/dto"; field gto "$tmp/sec" >> "$tmp/gto"; field total "$tmp/sec" >> "$tmp/tot"
        done
        links=$(tr -d '\n' < "$tmp/j" | grep -o '"links":{[^}]*}')
        printf '| %s | %s | %.2f | %.2f | %.2f | %s | %s | %s | %s | %.1f | %s |\n' "$s" "$q" \
            "$(median < "$tmp/dto")" "$(median < "$tmp/gto")" "$(median < "$tmp/tot")" \
            "$(echo "$links" | grep -o '"dto":[0-9]*' | cut -d: -f2)" \
            "$(echo "$links" | grep -o '"gto":[0-9]*' | cut -d: -f2)" \
            "$(echo "$links" | grep -o '"gathered":[0-9]*' | cut -d: -f2)" \
            "$(tr -d '\n' < "$tmp/j" | grep -o '"entries":{[^}]*}' | grep -o '"gto":[0-9]*' | cut -d: -f2)" \
            "$(awk -v b="$(field bytes "$tmp/j")" 'BEGIN {print b / 1048576}')" "$(field bounces "$tmp/j")"
    done
done
