#!/usr/bin/env bash
# tests/layers.sh BUILD: no #include points up or sideways in the layering
# (tools/check-layers.sh prints each one that does). Prints "N passed, N failed".
cd "$(dirname "$0")/.."
. tests/lib.sh layers.sh
if out=$(bash tools/check-layers.sh); then ok "no upward includes"; else echo "upward includes:"; echo "$out"; ko "upward includes"; fi
summary
