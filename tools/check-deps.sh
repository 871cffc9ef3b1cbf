#!/usr/bin/env bash
# check-deps.sh: before the first compile, names the Debian packages whose headers are
# missing and the command that installs them (instead of a compiler error about one
# header). Usage: tools/check-deps.sh [CXX]. Exit 0 if all is there.
set -u
cxx=${1:-g++}
if ! command -v "$cxx" >/dev/null 2>&1; then
    echo "wrt: no C++ compiler '$cxx': install the packages gcc g++ make (sudo apt-get install gcc g++ make)" >&2
    exit 1
fi
# header : package
need=(embree3/rtcore.h:libembree-dev OpenImageIO/imageio.h:libopenimageio-dev tiny_gltf.h:libtinygltf-dev
      stb_image.h:libstb-dev nlohmann/json.hpp:nlohmann-json3-dev GLFW/glfw3.h:libglfw3-dev
      EGL/egl.h:libegl-dev GL/glcorearb.h:libgl-dev)
missing=()
for hp in "${need[@]}"; do
    h=${hp%%:*}; p=${hp##*:}
    printf '#include <%s>\n' "$h" | "$cxx" -E -x c++ -I/usr/include/stb - >/dev/null 2>&1 || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
{
    echo "wrt: cannot build: these Debian packages are missing: ${missing[*]}"
    echo "     install them with:  sudo apt-get install ${missing[*]}"
    echo "     or install everything wrt uses (tests included):  make deps"
} >&2
exit 1
