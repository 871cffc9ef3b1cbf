#!/usr/bin/env python3
"""tools/textured_cornell.py OUT.gltf: the Cornell box with a textured floor and a
textured back wall (docs/textures.md), one self-contained glTF 2.0 file (buffers and
PNG images embedded as data URIs). Python's standard library only (zlib for the PNGs).

- floor: 4 x 4 quads over [-0.5, 0.5]^2, UV (0..1) across the whole floor, and a
  baseColorTexture of 4 x 4 squares (16 x 16 texels each), albedo 0.8 and 0.05: every
  floor element covers one square, so its own albedo is 0.8 or 0.05 while the
  material's mean is 0.425.
- back wall: 2 x 2 quads, a texture of four 8 x 8-texel blocks (orange, teal, white,
  dark blue), baseColorFactor (1, 1, 1); its UV t runs up the wall.
- red and green side walls, white ceiling, the two white boxes, and the point light of
  wrt-scenegen's cornell (2.5 cd at (0, 0.85, 0)).
Texels are written sRGB-encoded (glTF's base colour textures are sRGB)."""
import base64, json, math, struct, sys, zlib


def srgb(x):
    x = min(max(x, 0.0), 1.0)
    v = 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055
    return int(round(v * 255))


def png(w, h, texel):
    raw = b"".join(b"\0" + b"".join(bytes(srgb(c) for c in texel(i, j)) for i in range(w)) for j in range(h))
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def checker(i, j):
    a = 0.8 if ((i // 16) + (j // 16)) % 2 == 0 else 0.05
    return (a, a, a)


WALL = [(0.85, 0.45, 0.1), (0.1, 0.6, 0.55), (0.85, 0.85, 0.85), (0.05, 0.08, 0.3)]


def wall(i, j):
    return WALL[(i // 8) + 2 * (j // 8)]


class Mesh:
    def __init__(self, name, material):
        self.name, self.material, self.pos, self.uv, self.idx = name, material, [], [], []

    def quad(self, p, uv=None, facing=None):
        """Corners in order around the quad; with `facing`, reversed if their normal
        (p1 - p0) x (p3 - p0) points away from it."""
        if facing is not None:
            e1 = [p[1][k] - p[0][k] for k in range(3)]
            e3 = [p[3][k] - p[0][k] for k in range(3)]
            n = (e1[1] * e3[2] - e1[2] * e3[1], e1[2] * e3[0] - e1[0] * e3[2], e1[0] * e3[1] - e1[1] * e3[0])
            if sum(n[k] * facing[k] for k in range(3)) < 0:
                p = [p[0], p[3], p[2], p[1]]
                uv = [uv[0], uv[3], uv[2], uv[1]] if uv else None
        b = len(self.pos)
        self.pos += p
        self.uv += uv if uv else [(0, 0), (1, 0), (1, 1), (0, 1)]
        self.idx += [b, b + 1, b + 2, b, b + 2, b + 3]


def grid(mesh, p0, du, dv, n):
    """n x n quads of the parallelogram p0 + s du + t dv, s, t in [0, 1]; UV = (s, t)."""
    for j in range(n):
        for i in range(n):
            s0, s1, t0, t1 = i / n, (i + 1) / n, j / n, (j + 1) / n
            pt = lambda s, t: tuple(p0[k] + s * du[k] + t * dv[k] for k in range(3))
            mesh.quad([pt(s0, t0), pt(s1, t0), pt(s1, t1), pt(s0, t1)], [(s0, t0), (s1, t0), (s1, t1), (s0, t1)])


def block(mesh, cx, cz, w, d, h, deg):
    a = math.radians(deg)
    ca, sa = math.cos(a), math.sin(a)
    lx, lz = [-w / 2, w / 2, w / 2, -w / 2], [-d / 2, -d / 2, d / 2, d / 2]
    b = [(cx + ca * lx[k] + sa * lz[k], 0.0, cz - sa * lx[k] + ca * lz[k]) for k in range(4)]
    t = [(x, h, z) for (x, _, z) in b]
    for k in range(4):
        k1 = (k + 1) % 4
        out = tuple(0.5 * (b[k][i] + b[k1][i]) - (cx, 0, cz)[i] for i in range(3))
        mesh.quad([b[k], b[k1], t[k1], t[k]], facing=out)
    mesh.quad([t[0], t[1], t[2], t[3]], facing=(0, 1, 0))


def main(out):
    mats = [
        {"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.75, 0.75, 1], "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.63, 0.065, 0.05, 1], "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "green", "pbrMetallicRoughness": {"baseColorFactor": [0.14, 0.45, 0.09, 1], "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "checker", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0, "roughnessFactor": 1}},
        {"name": "tiles", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}, "metallicFactor": 0, "roughnessFactor": 1}},
    ]
    meshes = []
    floor = Mesh("floor", 3)
    # UV t runs toward -z: the texture's top row (t = 0) at the front
    grid(floor, (-0.5, 0, 0.5), (1, 0, 0), (0, 0, -1), 4)
    meshes.append(floor)
    ceil = Mesh("ceiling", 0)
    ceil.quad([(-0.5, 1, -0.5), (0.5, 1, -0.5), (0.5, 1, 0.5), (-0.5, 1, 0.5)], facing=(0, -1, 0))
    meshes.append(ceil)
    back = Mesh("back_wall", 4)
    grid(back, (-0.5, 0, -0.5), (1, 0, 0), (0, 1, 0), 2)  # faces +z; UV t runs up
    meshes.append(back)
    left = Mesh("left_wall", 1)
    left.quad([(-0.5, 0, -0.5), (-0.5, 0, 0.5), (-0.5, 1, 0.5), (-0.5, 1, -0.5)], facing=(1, 0, 0))
    meshes.append(left)
    right = Mesh("right_wall", 2)
    right.quad([(0.5, 0, 0.5), (0.5, 0, -0.5), (0.5, 1, -0.5), (0.5, 1, 0.5)], facing=(-1, 0, 0))
    meshes.append(right)
    sbox, tbox = Mesh("short_box", 0), Mesh("tall_box", 0)
    block(sbox, 0.17, 0.20, 0.30, 0.30, 0.30, -17)
    block(tbox, -0.16, -0.13, 0.30, 0.30, 0.60, 17)
    meshes += [sbox, tbox]

    binary, views, accs, gmeshes = bytearray(), [], [], []
    for m in meshes:
        prim = {"attributes": {}, "material": m.material, "mode": 4}
        for kind, data, fmt, typ in (("POSITION", m.pos, "3f", "VEC3"), ("TEXCOORD_0", m.uv, "2f", "VEC2")):
            off = len(binary)
            for v in data:
                binary += struct.pack("<" + fmt, *v)
            views.append({"buffer": 0, "byteOffset": off, "byteLength": len(binary) - off, "target": 34962})
            acc = {"bufferView": len(views) - 1, "componentType": 5126, "count": len(data), "type": typ}
            if kind == "POSITION":
                acc["min"] = [min(v[k] for v in data) for k in range(3)]
                acc["max"] = [max(v[k] for v in data) for k in range(3)]
            accs.append(acc)
            prim["attributes"][kind] = len(accs) - 1
        off = len(binary)
        for i in m.idx:
            binary += struct.pack("<I", i)
        views.append({"buffer": 0, "byteOffset": off, "byteLength": len(binary) - off, "target": 34963})
        accs.append({"bufferView": len(views) - 1, "componentType": 5125, "count": len(m.idx), "type": "SCALAR"})
        prim["indices"] = len(accs) - 1
        gmeshes.append({"name": m.name, "primitives": [prim]})
    uri = lambda b, t: "data:%s;base64,%s" % (t, base64.b64encode(bytes(b)).decode())
    doc = {
        "asset": {"version": "2.0", "generator": "wrt tools/textured_cornell.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "ceiling_light", "type": "point", "color": [1, 1, 1], "intensity": 2.5}]}},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(meshes) + 2))}],
        "nodes": [{"mesh": i, "name": m.name} for i, m in enumerate(meshes)] + [
            {"name": "light", "translation": [0, 0.85, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "camera", "camera": 0, "translation": [0, 0.5, 1.9]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": math.radians(39.3), "znear": 0.01, "zfar": 1000}}],
        "meshes": gmeshes,
        "materials": mats,
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}],
        "images": [{"uri": uri(png(64, 64, checker), "image/png")}, {"uri": uri(png(16, 16, wall), "image/png")}],
        "accessors": accs,
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary), "uri": uri(binary, "application/octet-stream")}],
    }
    with open(out, "w") as f:
        json.dump(doc, f, indent=1)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: tools/textured_cornell.py OUT.gltf")
    main(sys.argv[1])
