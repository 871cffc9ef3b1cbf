#!/usr/bin/env bash
# triangles.sh: any triangle mesh loads and bakes (issue 21), through the programs.
# - wrt-bake --scan reports and exits 0 whenever the scene can be read: also a scene a
#   bake would refuse (a NaN corner), with --drop-bad, with any bake option; its --json
#   is one valid object with the elements by kind, what is refused or dropped, and the
#   estimate. The bake itself still refuses the NaN (exit 2).
# - tests/data/blender_shapes.gltf (tools/blender_shapes.py: Blender 3.4's primitives and
#   modifiers in a Cornell box, exported by Blender's glTF exporter): 608 triangles, none
#   refused or dropped; it bakes (quality 1 here; docs/triangles.md has the default
#   quality against the path tracer). Where Blender is installed the script is rerun and
#   its output must load the same.
# - tests/data/blender_smooth.gltf (tools/blender_smooth.py, smooth-shaded sphere and
#   Suzanne): its normals reach the .gto (1.3, section normals); cornell's flat ones do
#   not (1.2). Its script is rerun with Blender like the other.
# Prints "N passed, N failed". ~10 s (30 s more with Blender).
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
bake=$build/wrt-bake
pass=0; fail=0
ok() { pass=$((pass + 1)); echo "ok $1"; }
ko() { fail=$((fail + 1)); echo "FAIL $1"; }
tmp=$(mktemp -d /tmp/wrt_tri_XXXXXX)
trap 'rm -rf "$tmp"' EXIT

# --scan of a scene the bake refuses: exit 0, says so; with --drop-bad and bake options too
"$bake" --scan tests/data/bad_nan.gltf >"$tmp/scan.txt" 2>"$tmp/err"; rc=$?
[ $rc -eq 0 ] && grep -q "^bake: refused: triangles with non-finite corners" "$tmp/scan.txt" \
    && grep -q "^estimate at quality 5" "$tmp/scan.txt" && ok "--scan of a refused scene: exit 0, says refused" \
    || ko "--scan of a refused scene: exit $rc: $(cat "$tmp/err")"
for opts in "" "--drop-bad" "--drop-bad -q 3 --threads 1 --max-error 0.5 --eps-compress 1e-4"; do
    # shellcheck disable=SC2086
    "$bake" --scan tests/data/bad_nan.gltf --json $opts >"$tmp/scan.json" 2>"$tmp/err"; rc=$?
    want=$([ -z "$opts" ] && echo true || echo false)
    q=$(sed -n 's/.*-q \([0-9]\).*/\1/p' <<<"$opts"); q=${q:-5}
    python3 - "$tmp/scan.json" "$want" "$q" <<'PY' && [ $rc -eq 0 ] && ok "--scan --json $opts: valid, refused $want" || ko "--scan --json $opts: exit $rc"
import json, sys
j = json.load(open(sys.argv[1]))
sys.exit(0 if j["refused"] == (sys.argv[2] == "true") and j["non_finite"] == 2 and j["estimate"]["quality"] == int(sys.argv[3]) else 1)
PY
done
"$bake" tests/data/bad_nan.gltf -o "$tmp/nan.gto" >/dev/null 2>"$tmp/err"; rc=$?
[ $rc -eq 2 ] && grep -q "has a NaN" "$tmp/err" && [ ! -e "$tmp/nan.gto" ] && ok "the bake refuses the NaN (exit 2)" \
    || ko "the bake of a NaN scene: exit $rc"

# the Blender scene: every triangle loads; it bakes
scene=tests/data/blender_shapes.gltf
"$bake" --scan "$scene" --json >"$tmp/shapes.json" 2>"$tmp/err"
python3 - "$tmp/shapes.json" <<'PY' && ok "blender_shapes: 608 triangles, 0 refused, 0 dropped" || ko "blender_shapes scan: $(head -c 300 "$tmp/shapes.json")"
import json, sys
j = json.load(open(sys.argv[1]))
e = j["elements"]
ok = (j["triangles"] == 608 and j["non_finite"] == 0 and j["dropped"] == 0 and j["problems"] == []
      and j["quads"] == e["paired"] + 3 * e["triangles"] + e["twins"] and e["triangles"] > 100 and not j["refused"])
print("blender_shapes: %d triangles -> %d quads from pairs, %d triangles as 3 quads, %d elements" % (
      j["triangles"], e["paired"], e["triangles"], j["quads"]))
sys.exit(0 if ok else 1)
PY
"$bake" "$scene" -o "$tmp/shapes.gto" -q 1 --quiet >/dev/null 2>"$tmp/err" && "$bake" --info "$tmp/shapes.gto" --json >"$tmp/info.json" 2>>"$tmp/err" \
    && python3 -c "import json,sys; j=json.load(open(sys.argv[1])); sys.exit(0 if j['ok'] and j['counts']['quads'] == 844 else 1)" "$tmp/info.json" \
    && ok "blender_shapes bakes (quality 1) into a .gto of its 844 elements" || ko "blender_shapes bake: $(tail -n 3 "$tmp/err")"

# the smooth-shaded Blender scene (tools/blender_smooth.py): its vertex normals reach the
# .gto (section normals, one record per quad; 1.3 in a float file, inside 2.0 by default); a flat scene's do not
smooth=tests/data/blender_smooth.gltf
"$bake" "$smooth" -o "$tmp/smooth.gto" -q 1 --quiet >/dev/null 2>"$tmp/err" && "$bake" --info "$tmp/smooth.gto" --json >"$tmp/sinfo.json" 2>>"$tmp/err" \
    && "$bake" assets/cornell.gltf -o "$tmp/cornell.gto" -q 1 --quiet >/dev/null 2>>"$tmp/err" \
    && "$bake" --info "$tmp/cornell.gto" --json >"$tmp/cinfo.json" 2>>"$tmp/err" \
    && python3 - "$tmp/sinfo.json" "$tmp/cinfo.json" <<'PY' && ok "blender_smooth: 1227 corner normals (section 18); cornell (flat, with NORMAL) has none" || ko "blender_smooth normals: $(tail -n 3 "$tmp/err")"
import json, sys
s, c = (json.load(open(p)) for p in sys.argv[1:3])
n = {x["name"]: x["count"] for x in s["sections"]}
sys.exit(0 if s["ok"] and c["ok"] and n.get("normals") == 1227
         and all(x["name"] != "normals" for x in c["sections"]) else 1)
PY

# Blender's glTF exporter needs numpy in Blender's own Python (Debian: python3-numpy)
if command -v blender >/dev/null 2>&1 &&
   timeout 120 blender -b --factory-startup --python-exit-code 3 --python-expr "import numpy" >/dev/null 2>&1; then
    if timeout 300 blender -b --factory-startup --python-exit-code 3 --python tools/blender_shapes.py -- "$tmp/again.gltf" >"$tmp/blender.log" 2>&1 \
        && "$bake" --scan "$tmp/again.gltf" --json >"$tmp/again.json" 2>>"$tmp/err"; then
        python3 - "$tmp/shapes.json" "$tmp/again.json" <<'PY' && ok "tools/blender_shapes.py rerun: the same elements" || ko "tools/blender_shapes.py rerun differs"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
keys = ("triangles", "quads", "elements", "triangles_alone", "dropped", "non_finite")
sys.exit(0 if all(a[k] == b[k] for k in keys) else 1)
PY
    else
        ko "tools/blender_shapes.py: $(tail -n 5 "$tmp/blender.log")"
    fi
    if timeout 300 blender -b --factory-startup --python-exit-code 3 --python tools/blender_smooth.py -- "$tmp/smooth_again.gltf" >"$tmp/blender2.log" 2>&1 \
        && "$bake" --scan "$smooth" --json >"$tmp/smooth.json" 2>>"$tmp/err" \
        && "$bake" --scan "$tmp/smooth_again.gltf" --json >"$tmp/smooth_again.json" 2>>"$tmp/err"; then
        python3 - "$tmp/smooth.json" "$tmp/smooth_again.json" <<'PY' && ok "tools/blender_smooth.py rerun: the same elements" || ko "tools/blender_smooth.py rerun differs"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
keys = ("triangles", "quads", "elements", "triangles_alone", "dropped", "non_finite")
sys.exit(0 if all(a[k] == b[k] for k in keys) else 1)
PY
    else
        ko "tools/blender_smooth.py: $(tail -n 5 "$tmp/blender2.log")"
    fi
else
    echo "skipped 1: Blender (with numpy) is not installed: tools/blender_shapes.py and blender_smooth.py not rerun"
    echo "triangles: $pass passed, $fail failed, 1 skipped"
    [ "$fail" -eq 0 ]; exit
fi
echo "triangles: $pass passed, $fail failed"
[ "$fail" -eq 0 ]
