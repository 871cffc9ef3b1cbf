#!/usr/bin/env bash
# scenegen.sh: tests wrt-scenegen (tools/scenegen.c). Generates every scene, checks each
# file with an independent glTF reader written here in Python (valid JSON, buffer and
# accessor sizes, POSITION min/max equal to the data, indices in range, triangle pairs
# forming exactly planar convex quads whose NORMAL agrees with the winding), then the
# geometry each scene promises (furnace and room faces look at the room's centre, the
# maze surface is one consistently oriented sheet, the squares of the test scenes sit at
# the distance or angle asked), the effect of each option, byte-identical reruns, that
# the committed assets are up to date, and wrt-bake --scan on each when it exists.
# Usage: tests/scenegen.sh BUILD. Prints "scenegen: N passed, N failed".
set -u
build=${1:-build}
cd "$(dirname "$0")/.."
gen=$build/wrt-scenegen
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
. tests/lib.sh scenegen
bad() { ko "$*"; }  # several words

if [ ! -x "$gen" ]; then
    make -s -j2 "$gen" >/dev/null 2>&1 || { bad "cannot build $gen"; summary; exit 1; }
fi

cat >"$tmp/check.py" <<'EOF'
# check.py FILE key=value...: validates a wrt-scenegen glTF file; prints problems, exits 1 on any.
import base64, json, math, struct, sys

path = sys.argv[1]
want = dict(a.split("=", 1) for a in sys.argv[2:])
errs = []
def err(msg): errs.append(msg)
def f32(x): return struct.unpack("<f", struct.pack("<f", x))[0]
def sub(a, b): return (a[0]-b[0], a[1]-b[1], a[2]-b[2])
def add(a, b): return (a[0]+b[0], a[1]+b[1], a[2]+b[2])
def dot(a, b): return a[0]*b[0]+a[1]*b[1]+a[2]*b[2]
def cross(a, b): return (a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0])
def norm(a):
    l = math.sqrt(dot(a, a)); return (a[0]/l, a[1]/l, a[2]/l) if l > 0 else a
def vec(s): return tuple(float(x) for x in s.split(","))
def near(a, b, tol): return all(abs(x - y) <= tol for x, y in zip(a, b))
def qrot(q, v):  # rotate v by unit quaternion q = (x, y, z, w)
    u = q[:3]; w = q[3]
    t = tuple(2*c for c in cross(u, v))
    return add(add(v, tuple(w*c for c in t)), cross(u, t))

g = json.load(open(path))
if g.get("asset", {}).get("version") != "2.0": err("asset.version is not 2.0")
bufs = g.get("buffers", [])
if len(bufs) != 1: err("want exactly one buffer")
uri = bufs[0]["uri"]; prefix = "data:application/octet-stream;base64,"
if not uri.startswith(prefix): err("buffer is not an embedded data URI")
data = base64.b64decode(uri[len(prefix):], validate=True)
if len(data) != bufs[0]["byteLength"]: err("buffer byteLength %d != decoded %d" % (bufs[0]["byteLength"], len(data)))
views = g["bufferViews"]
for i, v in enumerate(views):
    off = v.get("byteOffset", 0)
    if off % 4 or off + v["byteLength"] > len(data): err("bufferView %d out of the buffer" % i)
SIZE = {5126: 4, 5125: 4}; NCOMP = {"VEC3": 3, "SCALAR": 1}

def read(ai):
    a = g["accessors"][ai]; v = views[a["bufferView"]]
    n = a["count"] * NCOMP[a["type"]]; size = n * SIZE[a["componentType"]]
    if a.get("byteOffset", 0) + size > v["byteLength"]: err("accessor %d overruns its view" % ai)
    if size != v["byteLength"]: err("accessor %d does not fill its view" % ai)
    start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    vals = struct.unpack_from("<%d%s" % (n, "f" if a["componentType"] == 5126 else "I"), data, start)
    if a["type"] == "VEC3": return a, [tuple(vals[3*k:3*k+3]) for k in range(a["count"])]
    return a, list(vals)

mats = g.get("materials", [])
for m in mats:
    p = m.get("pbrMetallicRoughness", {})
    for k in ("baseColorFactor", "metallicFactor", "roughnessFactor"):
        if k not in p: err("material %s lacks %s" % (m.get("name"), k))
    if not all(0 <= c <= 1 for c in p.get("baseColorFactor", [])): err("baseColorFactor out of [0,1]")

quads = []  # (mesh name, corners a b c d, unit normal)
for mesh in g["meshes"]:
    for prim in mesh["primitives"]:
        if prim.get("mode", 4) != 4: err("mode is not triangles")
        pa, pos = read(prim["attributes"]["POSITION"]); _, nrm = read(prim["attributes"]["NORMAL"])
        _, idx = read(prim["indices"])
        if len(nrm) != len(pos): err("NORMAL count != POSITION count")
        lo = [min(p[c] for p in pos) for c in range(3)]; hi = [max(p[c] for p in pos) for c in range(3)]
        if [f32(x) for x in pa["min"]] != lo or [f32(x) for x in pa["max"]] != hi:
            err("%s: POSITION min/max %s %s != data %s %s" % (mesh["name"], pa["min"], pa["max"], lo, hi))
        if any(i >= len(pos) for i in idx): err("%s: index out of range" % mesh["name"])
        if mesh["name"] in want.get("trimeshes", "").split(","):  # loose triangles: each non-degenerate,
            for t in range(0, len(idx) - 2, 3):                   # its normals on its front side
                p0, p1, p2 = (pos[i] for i in idx[t:t+3]); n = cross(sub(p1, p0), sub(p2, p0))
                if dot(n, n) < 1e-20: err("%s: degenerate triangle %d" % (mesh["name"], t // 3))
                if any(dot(nrm[i], n) <= 0 for i in idx[t:t+3]): err("%s: a normal disagrees with the winding" % mesh["name"])
            continue
        if len(idx) % 6: err("%s: index count not a multiple of 6" % mesh["name"])
        for t in range(0, len(idx) - 5, 6):
            t0, t1 = idx[t:t+3], idx[t+3:t+6]
            shared = set(t0) & set(t1)
            if len(shared) != 2 or len(set(t0) | set(t1)) != 4: err("triangles %d,%d do not pair" % (t//3, t//3+1)); continue
            # quad in order: start at the first triangle's vertex after the diagonal
            k = [i for i in range(3) if t0[i] not in shared][0]
            a, b, c = t0[(k+1) % 3], t0[(k+2) % 3], t0[k]  # c is the lone corner of t0
            d = [i for i in t1 if i not in shared][0]
            q = [pos[c], pos[a], pos[d], pos[b]]  # around the quad: c, a, d, b
            n1 = cross(sub(pos[t0[1]], pos[t0[0]]), sub(pos[t0[2]], pos[t0[0]]))
            n2 = cross(sub(pos[t1[1]], pos[t1[0]]), sub(pos[t1[2]], pos[t1[0]]))
            n = norm(add(n1, n2))
            if dot(n1, n2) <= 0: err("%s: the two triangles of a quad face opposite ways" % mesh["name"])
            size = max(math.sqrt(dot(sub(q[i], q[0]), sub(q[i], q[0]))) for i in range(4))
            if math.sqrt(dot(n1, n1)) < 1e-12 or math.sqrt(dot(n2, n2)) < 1e-12: err("degenerate triangle")
            for p in q:
                if abs(dot(sub(p, q[0]), n)) > 1e-6 * size: err("%s: quad not planar" % mesh["name"]); break
            # convex: every turn around the quad has the same sense as the normal
            for i in range(4):
                e0 = sub(q[(i+1) % 4], q[i]); e1 = sub(q[(i+2) % 4], q[(i+1) % 4])
                if dot(cross(e0, e1), n) <= 0: err("%s: quad not convex (or twisted)" % mesh["name"]); break
            # c,a,d,b must run counter-clockwise about n (front face = CCW)
            if dot(cross(sub(q[1], q[0]), sub(q[3], q[0])), n) <= 0: err("%s: winding disagrees" % mesh["name"])
            for v in (a, b, c, d):
                if dot(norm(nrm[v]), n) < 0.9999: err("%s: NORMAL disagrees with winding" % mesh["name"]); break
            quads.append((mesh["name"], q, n))

# lights and camera
lights = g.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
if lights and "KHR_lights_punctual" not in g.get("extensionsUsed", []): err("lights without extensionsUsed")
lnodes = {}; cam = None
for nd in g["nodes"]:
    if "extensions" in nd:
        li = nd["extensions"]["KHR_lights_punctual"]["light"]
        if "translation" not in nd or "rotation" not in nd: err("light node lacks translation or rotation")
        lnodes[li] = nd
    if "camera" in nd: cam = nd
    if "rotation" in nd and abs(math.sqrt(sum(x*x for x in nd["rotation"])) - 1) > 1e-6: err("rotation not unit")
if sorted(lnodes) != list(range(len(lights))): err("every light needs exactly one node")
for L in lights:
    if L["type"] not in ("point", "spot", "directional") or L["intensity"] <= 0: err("bad light %s" % L)
    if L["type"] == "spot":
        s = L["spot"]
        if not (0 <= s["innerConeAngle"] < s["outerConeAngle"] <= math.pi / 2): err("bad spot cone")
if cam is None or g["cameras"][cam["camera"]]["perspective"]["yfov"] <= 0: err("no perspective camera node")
def ldir(i): return qrot(lnodes[i]["rotation"], (0, 0, -1))
camdir = qrot(cam["rotation"], (0, 0, -1)) if cam else (0, 0, -1)

allp = [p for _, q, _ in quads for p in q]
blo = tuple(min(p[c] for p in allp) for c in range(3)); bhi = tuple(max(p[c] for p in allp) for c in range(3))
bc = tuple((blo[c] + bhi[c]) / 2 for c in range(3))
def centroid(q): return tuple(sum(p[c] for p in q) / 4 for c in range(3))
def mesh_centre(name):
    ps = [p for m, q, _ in quads if m == name for p in q]
    return tuple((min(p[c] for p in ps) + max(p[c] for p in ps)) / 2 for c in range(3))

# expectations given on the command line
if "quads" in want and len(quads) != int(want["quads"]): err("%d quads, want %s" % (len(quads), want["quads"]))
if "lights" in want and len(lights) != int(want["lights"]): err("%d lights, want %s" % (len(lights), want["lights"]))
if "bbox" in want:
    b = vec(want["bbox"])
    if not (near(blo, b[:3], 1e-5) and near(bhi, b[3:], 1e-5)): err("bbox %s %s, want %s" % (blo, bhi, b))
if "light0" in want and not near(lnodes[0]["translation"], vec(want["light0"]), 1e-5): err("light 0 at %s" % lnodes[0]["translation"])
if "intensity" in want and abs(lights[0]["intensity"] - float(want["intensity"])) > 1e-5 * float(want["intensity"]):
    err("intensity %s, want %s" % (lights[0]["intensity"], want["intensity"]))
if "camera" in want and not near(cam["translation"], vec(want["camera"]), 1e-5): err("camera at %s" % cam["translation"])
if "camdir" in want and not near(camdir, vec(want["camdir"]), 1e-6): err("camera looks along %s" % (camdir,))
if "albedo" in want:
    m = mats[0]["pbrMetallicRoughness"]["baseColorFactor"]
    if not near(m[:3], (float(want["albedo"]),) * 3, 1e-6): err("first material %s" % m)
if "type" in want and any(L["type"] != want["type"] for L in lights): err("light types %s" % [L["type"] for L in lights])
if want.get("spotdown") and any(ldir(i)[1] > -0.5 for i in range(len(lights))): err("a spot does not point down")
if "ldir0" in want and not near(ldir(0), norm(vec(want["ldir0"])), 1e-6): err("light 0 points along %s" % (ldir(0),))
if want.get("lookat_bbox") and cam:
    to = norm(sub(bc, cam["translation"]))
    yfov = g["cameras"][0]["perspective"]["yfov"]
    if math.acos(max(-1, min(1, dot(to, camdir)))) > yfov / 2: err("camera does not look at the scene")
if "glossy" in want:  # name:roughness pairs
    for pair in want["glossy"].split(","):
        name, r = pair.split(":")
        m = [m for m in mats if m["name"] == name]
        if not m or abs(m[0]["pbrMetallicRoughness"]["roughnessFactor"] - float(r)) > 1e-6: err("material %s roughness" % name)

mode = want.get("mode", "")
if mode == "inward":  # every mesh is a closed room: faces look at its centre
    for name, q, n in quads:
        if dot(n, sub(mesh_centre(name), centroid(q))) <= 0: err("%s: a face looks away from the centre" % name); break
    for i in range(len(lights)):  # and lights sit inside a room
        p = lnodes[i]["translation"]
        inside = False
        for m in set(name for name, _, _ in quads):
            ps = [v for name, q, _ in quads if name == m for v in q]
            if all(min(v[c] for v in ps) < p[c] < max(v[c] for v in ps) for c in range(3)): inside = True
        if not inside: err("light %d is in no room" % i)
if mode == "room":  # meshes named *box face outwards, the rest look into the room
    for name, q, n in quads:
        c = mesh_centre(name)
        if name.endswith("box"):
            if dot(n, sub(centroid(q), c)) <= 0: err("%s: a face looks into the box" % name); break
        elif dot(n, sub(bc, centroid(q))) <= 0: err("%s: a face looks out of the room" % name); break
    for i in range(len(lights)):
        if lights[i]["type"] == "directional": continue  # a sun has no position
        p = lnodes[i]["translation"]
        if not all(blo[c] < p[c] < bhi[c] for c in (0, 2)): err("light %d outside the room" % i)
if mode == "sheet":  # maze: one oriented surface, open only along its outer bottom rim
    edges = {}
    for name, q, n in quads:
        if abs(abs(n[0]) + abs(n[1]) + abs(n[2]) - 1) > 1e-9: err("maze quad not axis-aligned"); break
        for i in range(4):
            e = (q[i], q[(i+1) % 4])
            edges[e] = edges.get(e, 0) + 1
    if any(v != 1 for v in edges.values()): err("a directed edge used twice (orientation flips)")
    rim = 0
    for (a, b) in edges:
        if (b, a) not in edges:
            on_rim = a[1] == blo[1] and b[1] == blo[1] and (
                (a[0] == b[0] and a[0] in (blo[0], bhi[0])) or (a[2] == b[2] and a[2] in (blo[2], bhi[2])))
            if not on_rim: err("open edge inside the maze %s %s" % (a, b)); break
            rim += 1
    if rim == 0: err("no rim found")
    if not any(n[1] > 0.5 and c[1] == blo[1] for _, q, n in quads for c in [centroid(q)]): err("no floor facing up")
    if any(n[1] < -0.5 for _, q, n in quads): err("a maze quad faces down")
if mode == "facing":
    (ma, qa, na) = quads[0]; (_, qb, nb) = [x for x in quads if x[0] != ma][0]
    if not near(na, tuple(-x for x in nb), 1e-9): err("squares not facing")
    gap = dot(sub(qb[0], qa[0]), na)
    if abs(gap - float(want["gap"])) > 1e-5 * float(want["gap"]): err("gap %g, want %s" % (gap, want["gap"]))
if mode == "hinge":  # first quad of each of the two meshes
    (ma, qa, na) = quads[0]; (_, qb, nb) = [x for x in quads if x[0] != ma][0]
    if len(set(qa) & set(qb)) != 2: err("squares do not share an edge")
    ang = math.degrees(math.pi - math.acos(max(-1, min(1, dot(na, nb)))))
    if abs(ang - float(want["angle"])) > 1e-4: err("opening angle %g, want %s" % (ang, want["angle"]))
    if dot(na, sub(centroid(qb), centroid(qa))) <= 0 or dot(nb, sub(centroid(qa), centroid(qb))) <= 0:
        err("hinged squares do not face into the wedge")

for e in errs[:8]: print("%s: %s" % (path, e))
sys.exit(1 if errs else 0)
EOF

check_gltf() {  # check_gltf NAME FILE key=value...
    local name=$1; shift
    if out=$(python3 "$tmp/check.py" "$@" 2>&1); then ok; else bad "$name: $out"; fi
}
run() {  # run NAME OUT SCENE options...: generate, counting a failure to run
    local name=$1 out=$2; shift 2
    if "$gen" "$@" --out "$out" >/dev/null 2>"$tmp/err"; then ok; else bad "$name: wrt-scenegen $*: $(cat "$tmp/err")"; fi
}

# default set: counts, validity, scene promises
if "$gen" --all "$tmp/all" >"$tmp/all.txt" 2>&1; then ok; else bad "--all: $(cat "$tmp/all.txt")"; fi
check_gltf cornell "$tmp/all/cornell.gltf" quads=15 lights=1 mode=room type=point camdir=0,0,-1 \
    bbox=-0.5,0,-0.5,0.5,1,0.5 albedo=0.75 lookat_bbox=1
check_gltf maze "$tmp/all/maze.gltf" quads=365 lights=3 mode=sheet type=spot spotdown=1 lookat_bbox=1
check_gltf glossy "$tmp/all/glossy.gltf" quads=9 lights=1 mode=room type=spot lookat_bbox=1 \
    ldir0=-1.2,-1.9,-1.4 glossy=glossy_floor:0.3,glossy_wall:0.4,orange:1
check_gltf facing "$tmp/all/test/facing.gltf" quads=2 lights=1 mode=facing gap=1 light0=0,0,0.5
check_gltf perpendicular "$tmp/all/test/perpendicular.gltf" quads=2 lights=1 mode=hinge angle=90
check_gltf furnace "$tmp/all/test/furnace.gltf" quads=6 lights=1 mode=inward light0=0,0,0 \
    bbox=-0.5,-0.5,-0.5,0.5,0.5,0.5
check_gltf tworooms "$tmp/all/test/tworooms.gltf" quads=12 lights=1 mode=inward
check_gltf grazing "$tmp/all/test/grazing.gltf" quads=2 lights=0 mode=hinge angle=1
check_gltf cornell-glossy "$tmp/all/test/cornell_glossy.gltf" quads=15 lights=1 mode=room type=point camdir=0,0,-1 \
    bbox=-0.5,0,-0.5,0.5,1,0.5 lookat_bbox=1 glossy=glossy_metal:0.3,white:1
check_gltf glossy-box "$tmp/all/test/glossy_box.gltf" quads=6 lights=1 mode=inward \
    bbox=-0.5,-0.5,-0.5,0.5,0.5,0.5 glossy=metal:0.3
check_gltf sun-room "$tmp/all/sun_room.gltf" quads=14 lights=1 mode=room type=directional \
    ldir0=1,-0.8,-0.3 bbox=-1,0,-1,1,1.5,1 lookat_bbox=1
"$gen" cornell-glossy --roughness 0.05 -o "$tmp/cg05.gltf" >/dev/null 2>&1
check_gltf cornell-glossy-0.05 "$tmp/cg05.gltf" quads=15 lights=1 mode=room type=point glossy=glossy_metal:0.05

# the committed assets are what the generator writes now
for f in cornell maze glossy sun_room test/facing test/perpendicular test/furnace test/tworooms test/grazing \
         test/cornell_glossy test/glossy_box test/cornell_shapes test/icosphere; do
    if cmp -s "$tmp/all/$f.gltf" "assets/$f.gltf"; then ok; else bad "assets/$f.gltf is stale (run make assets)"; fi
done

# determinism: same options, same bytes
"$gen" --all "$tmp/again" >/dev/null 2>&1
if diff -r -q "$tmp/all" "$tmp/again" >/dev/null; then ok; else bad "two runs differ"; fi

# options
run scale+offset "$tmp/c2.gltf" cornell --scale 2 --offset 100,-50,3 --albedo 0.5
check_gltf scale+offset "$tmp/c2.gltf" quads=15 mode=room bbox=99,-50,2,101,-48,4 light0=100,-48.3,3 \
    intensity=10 camera=100,-49,6.8 albedo=0.5 lookat_bbox=1
run cornell-res2 "$tmp/c3.gltf" cornell --res 2
check_gltf cornell-res2 "$tmp/c3.gltf" quads=60 mode=room
run cornell-spot "$tmp/c4.gltf" cornell --light spot --intensity 7
check_gltf cornell-spot "$tmp/c4.gltf" lights=1 type=spot ldir0=0,-1,0 intensity=7
run cornell-nolight "$tmp/c5.gltf" cornell --light none
check_gltf cornell-nolight "$tmp/c5.gltf" lights=0
if grep -q KHR_lights_punctual "$tmp/c5.gltf"; then bad "unlit scene still declares KHR_lights_punctual"; else ok; fi
run furnace-res3 "$tmp/f3.gltf" furnace --res 3 --albedo 0.3 --offset 5,5,5
check_gltf furnace-res3 "$tmp/f3.gltf" quads=54 mode=inward light0=5,5,5 albedo=0.3 bbox=4.5,4.5,4.5,5.5,5.5,5.5
run maze-res3 "$tmp/m2.gltf" maze --res 3 --offset 0.1,0.2,0.3 --scale 1.7
check_gltf maze-res3 "$tmp/m2.gltf" quads=3285 mode=sheet spotdown=1
run maze-small "$tmp/m3.gltf" maze --cells 3 --seed 7
check_gltf maze-small "$tmp/m3.gltf" mode=sheet lights=3
run maze-seed "$tmp/m4.gltf" maze --seed 2
if cmp -s "$tmp/m4.gltf" "$tmp/all/maze.gltf"; then bad "--seed changes nothing"; else ok; fi
run facing-dist "$tmp/fa.gltf" facing --dist 0.01 --scale 3
check_gltf facing-dist "$tmp/fa.gltf" mode=facing gap=0.03
run grazing-30 "$tmp/g30.gltf" grazing --angle 30 --res 4 --light point
check_gltf grazing-30 "$tmp/g30.gltf" quads=32 lights=1 mode=hinge angle=30
run grazing-179 "$tmp/g179.gltf" grazing --angle 179.5 --offset -3,2,1
check_gltf grazing-179 "$tmp/g179.gltf" mode=hinge angle=179.5
run tworooms-thick "$tmp/t2.gltf" tworooms --thick 0.001 --res 2
check_gltf tworooms-thick "$tmp/t2.gltf" quads=48 mode=inward
run glossy-res "$tmp/gl.gltf" glossy --res 3 --scale 0.5
check_gltf glossy-res "$tmp/gl.gltf" quads=81 mode=room intensity=5

# bad arguments are refused with status 1 (bad command line) and write nothing
for args in "cornell --res 0" "cornell --albedo 1.5" "nosuch" "cornell --offset 1,2" "cornell --light blue" \
            "grazing --angle 0" "cornell --scale -1" "cornell --res 2.5"; do
    # shellcheck disable=SC2086
    "$gen" $args --out "$tmp/bad.gltf" >/dev/null 2>&1; rc=$?
    if [ $rc -eq 1 ] && [ ! -e "$tmp/bad.gltf" ]; then ok; else bad "wrt-scenegen $args: status $rc"; fi
done

# the loader accepts every file, when wrt-bake is built
if [ -x "$build/wrt-bake" ]; then
    for f in "$tmp"/all/*.gltf "$tmp"/all/test/*.gltf "$tmp/m2.gltf" "$tmp/g179.gltf"; do
        if out=$("$build/wrt-bake" --scan "$f" 2>&1); then ok; else bad "wrt-bake --scan $f: $(tail -n 3 <<<"$out")"; fi
    done
fi

# the triangle scenes (issue 21): every triangle loads, nothing dropped; the sphere's caps,
# the bevelled box's corners and the icosphere's faces become triangle elements, the
# rest pairs into quads (counts by construction: sphere 16 x 8, cylinder 12 sides,
# bevelled box 30 triangles, icosphere 20 x 4^res)
if [ -x "$build/wrt-bake" ]; then
    "$build/wrt-bake" --scan "$tmp/all/test/cornell_shapes.gltf" --json >"$tmp/shapes.json" 2>&1
    "$gen" icosphere --res 2 -o "$tmp/ico2.gltf" >/dev/null 2>&1
    "$build/wrt-bake" --scan "$tmp/ico2.gltf" --json >"$tmp/ico2.json" 2>&1
    if python3 - "$tmp/shapes.json" "$tmp/ico2.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); i = json.load(open(sys.argv[2]))
e = s["elements"]
# 5 walls + sphere (16 x 6 band quads + 32 cap triangles) + cylinder (12 sides + 6 cap quads)
# + bevelled box (13 flat faces as pairs + 4 corner triangles)
ok = (s["triangles"] == 10 + 224 + 36 + 30 and e["paired"] == 5 + 96 + 18 + 13 and e["triangles"] == 32 + 4
      and s["dropped"] == 0 and s["non_finite"] == 0 and s["problems"] == []
      and i["elements"]["triangles"] == 320 and i["quads"] == 960 and i["dropped"] == 0)
sys.exit(0 if ok else 1)
PY
    then ok; else bad "cornell-shapes / icosphere scans: $(head -c 400 "$tmp/shapes.json")"; fi
    # --detail D multiplies the sphere's segments and rings and the cylinder's sides: at 2,
    # sphere 32 x 16 (2 x 32 x 15 triangles: 32 x 14 band quads, 64 cap triangles),
    # cylinder 24 sides (72 triangles: 24 side quads, 12 cap pairs); walls and box as at 1
    "$gen" cornell-shapes --detail 2 -o "$tmp/shapes2.gltf" >/dev/null 2>&1
    "$build/wrt-bake" --scan "$tmp/shapes2.gltf" --json >"$tmp/shapes2.json" 2>&1
    if python3 - "$tmp/shapes2.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1])); e = s["elements"]
ok = (s["triangles"] == 10 + 960 + 72 + 30 and e["paired"] == 5 + 448 + 36 + 13 and e["triangles"] == 64 + 4
      and s["dropped"] == 0 and s["problems"] == [])
sys.exit(0 if ok else 1)
PY
    then ok; else bad "cornell-shapes --detail 2 scan: $(head -c 400 "$tmp/shapes2.json")"; fi
fi
# --detail 1 is the scene as it was before the option (the committed test scene's bytes)
"$gen" cornell-shapes --detail 1 -o "$tmp/shapes1.gltf" >/dev/null 2>&1
if cmp -s "$tmp/shapes1.gltf" "$tmp/all/test/cornell_shapes.gltf"; then ok; else bad "cornell-shapes --detail 1 differs from the default"; fi

# the atrium (issue 22's scale benchmark): valid, closed as seen from its light (rays from
# the light in 400 fixed directions all meet the front of a face: nothing escapes, nothing
# is seen from behind), the same bytes twice, elements growing as about detail^1.7 as
# --help states (--scan's count), no triangle dropped or refused
run atrium-half "$tmp/at05.gltf" atrium --detail 0.5
run atrium-1 "$tmp/at1.gltf" atrium
check_gltf atrium "$tmp/at05.gltf" trimeshes=arcade_fans,columns,banner_tips_red,banner_tips_blue lights=1 type=point light0=0,3,0 lookat_bbox=1 bbox=-8,0,-6.4,8,8,6.4
"$gen" atrium -o "$tmp/at1b.gltf" >/dev/null 2>&1
if cmp -s "$tmp/at1.gltf" "$tmp/at1b.gltf"; then ok; else bad "atrium: two runs differ"; fi
if python3 - "$tmp/at05.gltf" <<'PY'
import base64, json, math, struct, sys
g = json.load(open(sys.argv[1]))
data = base64.b64decode(g["buffers"][0]["uri"].split(",", 1)[1])
def acc(i):
    a = g["accessors"][i]; v = g["bufferViews"][a["bufferView"]]
    n = a["count"] * (3 if a["type"] == "VEC3" else 1)
    vals = struct.unpack_from("<%d%s" % (n, "f" if a["componentType"] == 5126 else "I"), data, v.get("byteOffset", 0))
    return [vals[3*k:3*k+3] for k in range(a["count"])] if a["type"] == "VEC3" else vals
tris = []
for m in g["meshes"]:
    for p in m["primitives"]:
        P = acc(p["attributes"]["POSITION"]); I = acc(p["indices"])
        tris += [(P[I[k]], P[I[k+1]], P[I[k+2]]) for k in range(0, len(I), 3)]
L = (0.0, 3.0, 0.0)
sub = lambda a, b: (a[0]-b[0], a[1]-b[1], a[2]-b[2])
dot = lambda a, b: a[0]*b[0]+a[1]*b[1]+a[2]*b[2]
cross = lambda a, b: (a[1]*b[2]-a[2]*b[1], a[2]*b[0]-a[0]*b[2], a[0]*b[1]-a[1]*b[0])
pre = [(a, sub(b, a), sub(c, a), cross(sub(b, a), sub(c, a))) for a, b, c in tris]
bad = 0; n = 400; ga = math.pi * (3 - math.sqrt(5))
for k in range(n):  # a Fibonacci sphere of directions
    y = 1 - 2 * (k + 0.5) / n; r = math.sqrt(1 - y * y); d = (r * math.cos(ga * k), y, r * math.sin(ga * k))
    best, front = 1e30, None
    for a, e1, e2, nrm in pre:
        p = cross(d, e2); det = dot(e1, p)
        if abs(det) < 1e-12: continue
        s = sub(L, a); u = dot(s, p) / det
        if u < 0 or u > 1: continue
        q = cross(s, e1); v = dot(d, q) / det
        if v < 0 or u + v > 1: continue
        t = dot(e2, q) / det
        if 1e-6 < t < best: best, front = t, dot(nrm, d) < 0
    if front is not True: bad += 1
print("%d of %d rays escape or meet a back face" % (bad, n))
sys.exit(0 if bad == 0 else 1)
PY
then ok; else bad "atrium is not closed and facing its light"; fi
for args in "atrium --detail 0.1" "atrium --detail 17" "atrium --detail x"; do
    # shellcheck disable=SC2086
    "$gen" $args --out "$tmp/bad.gltf" >/dev/null 2>&1; rc=$?
    if [ $rc -eq 1 ] && [ ! -e "$tmp/bad.gltf" ]; then ok; else bad "wrt-scenegen $args: status $rc"; fi
done
if [ -x "$build/wrt-bake" ]; then
    "$gen" atrium --detail 2 -o "$tmp/at2.gltf" >/dev/null 2>&1
    for d in 05 1 2; do "$build/wrt-bake" --scan "$tmp/at$d.gltf" --json >"$tmp/at$d.json" 2>"$tmp/at$d.err"; done
    if python3 - "$tmp/at05.json" "$tmp/at1.json" "$tmp/at2.json" <<'PY'
import json, sys
s = [json.load(open(f)) for f in sys.argv[1:]]
n = [x["quads"] for x in s]
ok = all(x["dropped"] == 0 and x["non_finite"] == 0 and x["problems"] == [] for x in s)
ok = ok and 2000 <= n[1] <= 3500 and 2.3 <= n[1] / n[0] <= 3.6 and 2.3 <= n[2] / n[1] <= 3.6  # 2^1.7 = 3.2
ok = ok and all(x["elements"]["triangles"] > 0 and x["elements"]["paired"] > 0 for x in s)  # both kinds
print(n); sys.exit(0 if ok else 1)
PY
    then ok; else bad "atrium scans: $(cat "$tmp/at1.err" | head -c 300)"; fi
fi

summary
