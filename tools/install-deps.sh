#!/usr/bin/env bash
# Installs the Debian 12 packages wrt needs, if any is missing. Needs root (or sudo)
# only when something is missing; prints nothing when all is there.
set -euo pipefail
pkgs=(gcc g++ make clang libclang-rt-14-dev
      libembree-dev libopenimageio-dev libtinygltf-dev libstb-dev nlohmann-json3-dev
      libglfw3-dev libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri
      xvfb xauth xdotool jq gnuplot-nox python3 bc
      libopenmpi-dev openmpi-bin)
missing=()
for p in "${pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "install-deps: installing ${missing[*]}" >&2
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -q >&2
$sudo apt-get install -y -q --no-install-recommends "${missing[@]}" >&2
