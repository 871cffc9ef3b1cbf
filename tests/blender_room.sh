#!/usr/bin/env bash
# blender_room.sh: the room of tests/data/blender_room.gltf, modelled in Blender 3.4 from
# a cube (normals out, as Blender makes them) and exported by Blender's own glTF exporter
# with doubleSided materials (tools/blender_room.py made it). It loads with no problem and
# a back-to-back twin for each quad; baked, every wall's inner side receives indirect
# light, as the path tracer (wrt-ref, an independent code) says, and the bake's cell
# error against it stays within a bound that a bake ignoring doubleSided fails (walls
# black: the control with doubleSided removed). Prints "N passed, N failed". ~10 s.
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
bake=$build/wrt-bake
. tests/lib.sh blender_room
tmp=$(mktemp -d /tmp/wrt_room_XXXXXX)
trap 'rm -rf "$tmp"' EXIT
scene=tests/data/blender_room.gltf
"$bake" --scan "$scene" --json > "$tmp/scan.json" 2>"$tmp/err"
python3 - "$tmp/scan.json" <<'PY' && ok "scan: 88 quads, 44 twins, no problem" || ko "scan: 88 quads, 44 twins, no problem"
import json, sys
j = json.load(open(sys.argv[1]))
sys.exit(0 if j["quads"] == 88 and j["double_sided_twins"] == 44 and j["problems"] == [] else 1)
PY
sed 's/"doubleSided" *: *true/"doubleSided" : false/g' "$scene" > "$tmp/one_sided.gltf"
"$bake" "$scene" -o "$tmp/room.gto" -q 2 --quiet >/dev/null 2>"$tmp/err" && ok "bake" || ko "bake"
"$bake" "$tmp/one_sided.gltf" -o "$tmp/one.gto" -q 2 --quiet >/dev/null 2>>"$tmp/err" && ok "control bake" || ko "control bake"
args=(--lights 1 --cell-paths 200000 --no-image --per-quad --bench 1)
"$build/wrt-compare" "$scene" "$tmp/room.gto" "${args[@]}" > "$tmp/room.json" 2>>"$tmp/err"
"$build/wrt-compare" "$tmp/one_sided.gltf" "$tmp/one.gto" "${args[@]}" > "$tmp/one.json" 2>>"$tmp/err"
python3 - "$tmp/room.json" "$tmp/one.json" <<'PY'
import json, sys
room = json.load(open(sys.argv[1]))["bakes"][0]
one = json.load(open(sys.argv[2]))["bakes"][0]
def walls(b, twins):
    # material 0 is the walls; the twins (facing into the room) follow the 44 front quads
    return [q for q in b["quads"] if q["material"] == 0 and (q["quad"] >= 44) == twins]
res = []
inner = walls(room, True)
lit = [q for q in inner if min(q["reference"]) > 0.5 and min(q["wavelet"]) > 0.5]
res.append((len(inner) == 14 and len(lit) == len(inner),
            "every inner wall face lit, bake and path tracer (%d of %d)" % (len(lit), len(inner))))
outer = walls(room, False)
res.append((all(max(q["reference"]) == 0 and max(q["wavelet"]) == 0 for q in outer),
            "outer wall faces receive nothing (%d)" % len(outer)))
res.append((room["cell_rmse"] < 0.12, "cell error %.4f < 0.12 (reference floor %.4f)" % (room["cell_rmse"], room["cell_floor"])))
w1 = [q for q in one["quads"] if q["material"] == 0]
res.append((all(max(q["reference"]) == 0 for q in w1) and len(one["quads"]) == 44,
            "control, doubleSided removed: 44 quads, the walls receive nothing (as the issue found)"))
for good, name in res:
    print(("ok " if good else "FAIL ") + name)
sys.exit(0 if all(g for g, _ in res) else 1)
PY
rc=$?
n=4; if [ $rc -eq 0 ]; then pass=$((pass + n)); else fail=$((fail + 1)); fi
summary
