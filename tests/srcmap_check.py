# srcmap_check.py GLTF ENGINE_OUTPUT: the quad-to-source map printed by examples/engine.c
# checked against the glTF itself (read here, independently of the loader): each quad's
# node places its mesh; a pair's corners are the vertices of its two triangles (which share
# an edge) and its uv their TEXCOORD_0; a triangle's part k has the corners V_k, the edge
# midpoints and the centroid; a twin names an earlier front with the same source, its
# corners reversed (p0 p3 p2 p1, set back by less than 1e-3) and so its uv; every triangle
# of every placed primitive is covered exactly once by the fronts. Handles root nodes
# with translation, rotation and scale. Exit 1 on any disagreement.
import base64, json, struct, sys, os
gltf_path, txt = sys.argv[1], sys.argv[2]
j = json.load(open(gltf_path))
bufs = []
for b in j["buffers"]:
    u = b["uri"]
    bufs.append(base64.b64decode(u.split(",", 1)[1]) if u.startswith("data:") else
                open(os.path.join(os.path.dirname(gltf_path), u), "rb").read())
def acc(i):
    a = j["accessors"][i]; bv = j["bufferViews"][a["bufferView"]]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[a["type"]]
    fmt = {5126: "f", 5123: "H", 5125: "I", 5121: "B"}[a["componentType"]]
    size = struct.calcsize(fmt); stride = bv.get("byteStride", n * size)
    base = bv.get("byteOffset", 0) + a.get("byteOffset", 0); data = bufs[bv["buffer"]]
    return [struct.unpack_from("<%d%s" % (n, fmt), data, base + k * stride) for k in range(a["count"])]
quads, sup = [], []
for line in open(txt):
    w = line.split()
    if w[0] != "quad": continue
    q = dict(idx=int(w[1]), node=int(w[3]), mesh=int(w[5]), prim=int(w[7]), kind=w[9], part=int(w[11]),
             tris=(int(w[13]), int(w[14])), twin=int(w[16]), of=int(w[18]))
    k = w.index("uv"); c = w.index("corners")
    q["uv"] = None if w[k + 1] == "none" else [(float(w[k + 1 + 2 * i]), float(w[k + 2 + 2 * i])) for i in range(4)]
    q["p"] = [tuple(float(x) for x in w[c + 1 + 3 * i:c + 4 + 3 * i]) for i in range(4)]
    quads.append(q)
close = lambda a, b, t=1e-6: all(abs(x - y) <= t for x, y in zip(a, b))
bad, covered = [], set()
for q in quads:
    if q["twin"] == 1:
        f = quads[q["of"]]
        same = all(q[key] == f[key] for key in ("node", "mesh", "prim", "tris", "kind", "part"))
        corners = all(close(q["p"][k], f["p"][(4 - k) % 4], 1e-3) for k in range(4))
        uv = q["uv"] == [f["uv"][(4 - k) % 4] for k in range(4)] if f["uv"] else q["uv"] is None
        if not (same and corners and uv and f["twin"] == 0): bad.append("twin %d of %d" % (q["idx"], q["of"]))
        continue
    node = j["nodes"][q["node"]]
    if node.get("mesh") != q["mesh"]: bad.append("quad %d: node %d places mesh %s" % (q["idx"], q["node"], node.get("mesh"))); continue
    t = node.get("translation", [0, 0, 0]); qx, qy, qz, qw = node.get("rotation", [0, 0, 0, 1]); sc = node.get("scale", [1, 1, 1])
    R = [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
         [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
         [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]
    if "matrix" in node or any(q["node"] in nd.get("children", []) for nd in j["nodes"]):
        bad.append("node %d: a matrix or a parent (the check handles root TRS nodes only)" % q["node"]); continue
    pr = j["meshes"][q["mesh"]]["primitives"][q["prim"]]
    pos = acc(pr["attributes"]["POSITION"]); ind = [i[0] for i in acc(pr["indices"])]
    uvs = acc(pr["attributes"]["TEXCOORD_0"]) if "TEXCOORD_0" in pr["attributes"] else None
    world = lambda v: tuple(t[i] + sum(R[i][k] * sc[k] * pos[v][k] for k in range(3)) for i in range(3))
    if q["kind"] == "pair":
        verts = [ind[3 * tr + i] for tr in q["tris"] for i in range(3)]
        for k in range(4):
            m = [v for v in verts if close(world(v), q["p"][k])]
            if not m: bad.append("quad %d corner %d is no vertex of triangles %s" % (q["idx"], k, q["tris"])); break
            if uvs and not close(uvs[m[0]], q["uv"][k]): bad.append("quad %d corner %d uv %s, glTF %s" % (q["idx"], k, q["uv"][k], uvs[m[0]]))
        if len({tuple(round(x, 6) for x in world(v)) for v in verts}) != 4: bad.append("quad %d: triangles do not share an edge" % q["idx"])
        for tr in q["tris"]: covered.add((q["node"], q["prim"], tr))
    else:
        tr = q["tris"][0]; V = [world(ind[3 * tr + i]) for i in range(3)]; k = q["part"]
        mid = lambda a, b: tuple(0.5 * (x + y) for x, y in zip(a, b))
        g = tuple(sum(x) / 3 for x in zip(*V))
        want = [V[k], mid(V[k], V[(k + 1) % 3]), g, mid(V[(k + 2) % 3], V[k])]
        if not all(close(want[i], q["p"][i]) for i in range(4)): bad.append("quad %d: not part %d of triangle %d" % (q["idx"], k, tr))
        if uvs and q["uv"]:
            U = [uvs[ind[3 * tr + i]] for i in range(3)]
            wuv = [U[k], mid(U[k], U[(k + 1) % 3]), tuple(sum(x) / 3 for x in zip(*U)), mid(U[(k + 2) % 3], U[k])]
            if not all(close(wuv[i], q["uv"][i]) for i in range(4)): bad.append("quad %d: uv not part %d of triangle %d's" % (q["idx"], k, tr))
        covered.add((q["node"], q["prim"], tr))
    if (uvs is None) != (q["uv"] is None): bad.append("quad %d: uv presence differs from the glTF" % q["idx"])
alltris = {(n, p, tr) for n, nd in enumerate(j["nodes"]) if "mesh" in nd
           for p, pr in enumerate(j["meshes"][nd["mesh"]]["primitives"]) for tr in range(len(acc(pr["indices"])) // 3)}
if covered != alltris: bad.append("triangles covered %d, the glTF has %d" % (len(covered), len(alltris)))
print("%d quads (%d twins), %d triangles covered once each; %s" % (len(quads), sum(q["twin"] == 1 for q in quads), len(covered),
      "; ".join(bad[:5]) if bad else "all agree with the glTF"))
sys.exit(1 if bad else 0)
