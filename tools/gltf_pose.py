#!/usr/bin/env python3
"""An independent implementation of the glTF 2.0 posing rules, for checking furbake against.

Reads a .glb or .gltf (embedded, data: or relative buffer URIs), samples one animation at a time
(glTF 2.0 specification, "Animations" -> "Interpolation": STEP, LINEAR with quaternion slerp,
CUBICSPLINE with tangents scaled by the key interval; before the first key the first value holds,
after the last the last), computes every node's world matrix, and poses every triangle primitive
of the default scene: morph targets first (node or mesh default weights, or the clip's weights
channel), then linear blend skinning with JOINTS_0/1, WEIGHTS_0/1 (weights normalised; weights
summing to 0 bind wholly to the skin's first joint), or the node's world matrix for an unskinned
mesh ("Skins" -> "Skinned mesh": a skinned mesh ignores its node's transform).

Writes JSON: {"vertices": [[bind_x, bind_y, bind_z, posed_x, posed_y, posed_z], ...]} where the
bind position is where the vertex sits before any animation (mesh space for skinned meshes, the
node's world matrix in the rest pose for unskinned ones) - the key to match welded vertices by.

Only the Python standard library is used. Written from the specification, sharing no code with
furbake (Rust), so that the two can be compared.

usage: gltf_pose.py MODEL.glb [--animation NAME] [--time SECONDS] [-o OUT.json]
"""

import argparse
import base64
import json
import math
import os
import struct
import sys

COMPONENT = {5120: ("b", 1), 5121: ("B", 1), 5122: ("h", 2), 5123: ("H", 2), 5125: ("I", 4), 5126: ("f", 4)}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
NORM_DIV = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}


def load(path):
    with open(path, "rb") as f:
        data = f.read()
    binchunk = None
    if data[:4] == b"glTF":
        offset, doc = 12, None
        while offset < len(data):
            length, kind = struct.unpack_from("<II", data, offset)
            chunk = data[offset + 8: offset + 8 + length]
            if kind == 0x4E4F534A:
                doc = json.loads(chunk.decode("utf-8"))
            elif kind == 0x004E4942:
                binchunk = chunk
            offset += 8 + length
    else:
        doc = json.loads(data.decode("utf-8"))
    buffers = []
    for b in doc.get("buffers", []):
        uri = b.get("uri")
        if uri is None:
            buffers.append(binchunk)
        elif uri.startswith("data:"):
            buffers.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            from urllib.parse import unquote

            with open(os.path.join(os.path.dirname(path), unquote(uri)), "rb") as f:
                buffers.append(f.read())
    return doc, buffers


def accessor(doc, buffers, index):
    """The accessor's elements as lists of floats (normalised integers scaled)."""
    a = doc["accessors"][index]
    fmt, size = COMPONENT[a["componentType"]]
    width, count = WIDTH[a["type"]], a["count"]
    norm = a.get("normalized", False)

    def convert(v):
        return max(v / NORM_DIV[a["componentType"]], -1.0) if norm else float(v)

    out = [[0.0] * width for _ in range(count)]
    if "bufferView" in a:
        view = doc["bufferViews"][a["bufferView"]]
        buf = buffers[view["buffer"]]
        base = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        stride = view.get("byteStride", 0) or size * width
        for i in range(count):
            values = struct.unpack_from("<" + fmt * width, buf, base + i * stride)
            out[i] = [convert(v) for v in values]
    if "sparse" in a:
        sp = a["sparse"]
        ifmt, isize = COMPONENT[sp["indices"]["componentType"]]
        iview = doc["bufferViews"][sp["indices"]["bufferView"]]
        vview = doc["bufferViews"][sp["values"]["bufferView"]]
        ibase = iview.get("byteOffset", 0) + sp["indices"].get("byteOffset", 0)
        vbase = vview.get("byteOffset", 0) + sp["values"].get("byteOffset", 0)
        for k in range(sp["count"]):
            (i,) = struct.unpack_from("<" + ifmt, buffers[iview["buffer"]], ibase + k * isize)
            values = struct.unpack_from("<" + fmt * width, buffers[vview["buffer"]], vbase + k * size * width)
            out[i] = [convert(v) for v in values]
    return out


# 4x4 matrices as flat column-major lists of 16 floats.
def mat_mul(a, b):
    return [sum(a[r + 4 * k] * b[k + 4 * c] for k in range(4)) for c in range(4) for r in range(4)]


def trs(t, r, s):
    x, y, z, w = r
    xx, yy, zz, xy, xz, yz, wx, wy, wz = x * x, y * y, z * z, x * y, x * z, y * z, w * x, w * y, w * z
    rot = [1 - 2 * (yy + zz), 2 * (xy + wz), 2 * (xz - wy),
           2 * (xy - wz), 1 - 2 * (xx + zz), 2 * (yz + wx),
           2 * (xz + wy), 2 * (yz - wx), 1 - 2 * (xx + yy)]
    m = [0.0] * 16
    for c in range(3):
        for r_ in range(3):
            m[r_ + 4 * c] = rot[r_ + 3 * c] * s[c]
    m[12], m[13], m[14], m[15] = t[0], t[1], t[2], 1.0
    return m


def apply(m, p):
    return [m[r] * p[0] + m[r + 4] * p[1] + m[r + 8] * p[2] + m[r + 12] for r in range(3)]


def slerp(a, b, s):
    d = sum(x * y for x, y in zip(a, b))
    if d < 0:
        b, d = [-x for x in b], -d
    if d > 0.9995:
        q = [x + (y - x) * s for x, y in zip(a, b)]
    else:
        th = math.acos(min(d, 1.0))
        sa, sb = math.sin((1 - s) * th) / math.sin(th), math.sin(s * th) / math.sin(th)
        q = [sa * x + sb * y for x, y in zip(a, b)]
    n = math.sqrt(sum(x * x for x in q)) or 1.0
    return [x / n for x in q]


def sample(doc, buffers, sampler, path, t):
    times = [v[0] for v in accessor(doc, buffers, sampler["input"])]
    values = accessor(doc, buffers, sampler["output"])
    interp = sampler.get("interpolation", "LINEAR")
    per_key = len(values) // len(times) // (3 if interp == "CUBICSPLINE" else 1)
    flat = [c for v in values for c in v]
    width = len(values[0]) * per_key

    def key(k, which=1):
        e = 3 if interp == "CUBICSPLINE" else 1
        at = (k * e + (which if e == 3 else 0)) * width
        return flat[at: at + width]

    last = len(times) - 1
    if t <= times[0]:
        return key(0)
    if t >= times[last]:
        return key(last)
    k = max(i for i in range(len(times)) if times[i] <= t)
    if interp == "STEP":
        return key(k)
    td = times[k + 1] - times[k]
    s = (t - times[k]) / td
    if interp == "LINEAR":
        if path == "rotation":
            return slerp(key(k), key(k + 1), s)
        return [a + (b - a) * s for a, b in zip(key(k), key(k + 1))]
    s2, s3 = s * s, s * s * s
    h = [2 * s3 - 3 * s2 + 1, td * (s3 - 2 * s2 + s), -2 * s3 + 3 * s2, td * (s3 - s2)]
    v = [h[0] * a + h[1] * b + h[2] * c + h[3] * d
         for a, b, c, d in zip(key(k, 1), key(k, 2), key(k + 1, 1), key(k + 1, 0))]
    if path == "rotation":
        n = math.sqrt(sum(x * x for x in v)) or 1.0
        v = [x / n for x in v]
    return v


def pose(doc, buffers, animation, time_s):
    nodes = doc.get("nodes", [])
    local = []
    for n in nodes:
        local.append({
            "t": list(n.get("translation", [0, 0, 0])), "r": list(n.get("rotation", [0, 0, 0, 1])),
            "s": list(n.get("scale", [1, 1, 1])), "m": n.get("matrix"), "w": None,
        })
    if animation is not None:
        for ch in animation["channels"]:
            target = ch["target"]
            if "node" not in target:
                continue
            path = target["path"]
            v = sample(doc, buffers, animation["samplers"][ch["sampler"]], path, time_s)
            slot = local[target["node"]]
            if path == "weights":
                slot["w"] = v
            else:
                slot[path[0]] = v
                slot["m"] = None  # an animated node has TRS (the spec forbids matrix on targets)

    world = [None] * len(nodes)

    def visit(i, parent):
        l = local[i]
        m = l["m"] if l["m"] is not None else trs(l["t"], l["r"], l["s"])
        world[i] = mat_mul(parent, m)
        for c in nodes[i].get("children", []):
            visit(c, world[i])

    identity = [1.0 if r == c else 0.0 for c in range(4) for r in range(4)]
    scene = doc.get("scenes", [{"nodes": list(range(len(nodes)))}])[doc.get("scene", 0)]
    for root in scene["nodes"]:
        visit(root, identity)
    return world, local


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("model")
    ap.add_argument("--animation", help="animation name (default: none, the rest pose)")
    ap.add_argument("--time", type=float, default=0.0)
    ap.add_argument("-o", "--output")
    args = ap.parse_args()
    doc, buffers = load(args.model)
    anim = None
    if args.animation:
        found = [a for a in doc.get("animations", []) if a.get("name") == args.animation]
        if not found:
            sys.exit(f"{args.model}: no animation named {args.animation!r}")
        anim = found[0]
    world, local = pose(doc, buffers, anim, args.time)
    rest_world, _ = pose(doc, buffers, None, 0.0)
    out = []
    for ni, node in enumerate(doc.get("nodes", [])):
        if "mesh" not in node or world[ni] is None:
            continue
        mesh = doc["meshes"][node["mesh"]]
        weights = local[ni]["w"] or node.get("weights") or mesh.get("weights") or []
        skin = doc["skins"][node["skin"]] if "skin" in node else None
        if skin is not None:
            joints = skin["joints"]
            ibm = accessor(doc, buffers, skin["inverseBindMatrices"]) if "inverseBindMatrices" in skin else None
            palette = [mat_mul(world[j], ibm[k] if ibm else [1.0 if r == c else 0.0 for c in range(4) for r in range(4)])
                       for k, j in enumerate(joints)]
        for prim in mesh["primitives"]:
            if prim.get("mode", 4) != 4:
                continue
            attrs = prim["attributes"]
            positions = accessor(doc, buffers, attrs["POSITION"])
            morphed = [list(p) for p in positions]
            for t, target in enumerate(prim.get("targets", [])):
                w = weights[t] if t < len(weights) else 0.0
                if w != 0.0 and "POSITION" in target:
                    for i, d in enumerate(accessor(doc, buffers, target["POSITION"])):
                        for c in range(3):
                            morphed[i][c] += w * d[c]
            if skin is not None:
                sets = [(accessor(doc, buffers, attrs[f"JOINTS_{k}"]), accessor(doc, buffers, attrs[f"WEIGHTS_{k}"]))
                        for k in (0, 1) if f"JOINTS_{k}" in attrs and f"WEIGHTS_{k}" in attrs]
                for i, p in enumerate(morphed):
                    infl = [(int(js[i][c]), ws[i][c]) for js, ws in sets for c in range(4) if ws[i][c] > 0]
                    total = sum(w for _, w in infl)
                    if total <= 0:
                        infl, total = [(0, 1.0)], 1.0
                    m = [0.0] * 16
                    for j, w in infl:
                        for e in range(16):
                            m[e] += palette[j][e] * (w / total)
                    out.append(list(positions[i]) + apply(m, p))
            else:
                for i, p in enumerate(morphed):
                    out.append(apply(rest_world[ni], positions[i]) + apply(world[ni], p))
    text = json.dumps({"vertices": out})
    if args.output:
        with open(args.output, "w") as f:
            f.write(text)
    else:
        print(text)


if __name__ == "__main__":
    main()
