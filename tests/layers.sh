#!/usr/bin/env bash
# tests/layers.sh BUILD: no #include points up or sideways in the layering
# (tools/check-layers.sh prints each one that does). Prints "N passed, N failed".
cd "$(dirname "$0")/.."
if out=$(bash tools/check-layers.sh); then echo "layers.sh: 1 passed, 0 failed"; else echo "FAIL: upward includes:"; echo "$out"; echo "layers.sh: 0 passed, 1 failed"; exit 1; fi
