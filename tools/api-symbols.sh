#!/usr/bin/env bash
# tools/api-symbols.sh [HEADER]: the names of the functions a header exports, one a line:
# every declaration that starts with WRT_API (include/wrt.h by default). The Makefile
# keeps them when it links libwrt, and tests/exports.sh compares them with `nm -D`.
set -eu
sed -n 's/^WRT_API[^(]*[ *]\(wrt_[a-z0-9_]*\)(.*/\1/p' "${1:-include/wrt.h}" | sort -u
