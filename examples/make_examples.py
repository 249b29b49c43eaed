#!/usr/bin/env python3
"""Generate the prismbake example assets (meshes, height maps, sidecars).

Everything here is procedural and deterministic (fixed seeds, no timestamps), so running
the script again reproduces the committed files byte for byte.

    python3 -m pip install numpy OpenEXR      # the only dependencies
    python3 examples/make_examples.py         # writes into examples/ next to this file

Outputs (see examples/README.md):
    sphere/sphere.glb   sphere/sphere.prismbake.toml
    torus/torus.obj     torus/torus.prismbake.toml
    rock/rock.glb       rock/rock.prismbake.toml
    maps/rock_1024.png  maps/bumps_512.exr  maps/scales_256.png
    maps/rock_albedo_256.png  (the rock's base colour, also embedded in rock.glb)

Conventions (docs: /DESIGN.md "Conventions"):
  * glTF is Y-up, metres, TEXCOORD_0 v points DOWN the image (v_gltf = 1 - v_up);
    OBJ is Y-up, vt v points UP the image.
  * Triangles are counter-clockwise seen from outside; vertex normals are unit length.
The script also re-reads and checks what it wrote (GLB structure, PNG/EXR round trip,
normals, winding, watertightness, the rock's embedded texture) and fails loudly if anything
is off.
"""

from __future__ import annotations

import json
import math
import os
import struct
import sys
import zlib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CREASE_COS = 0.0436  # cos(87.5 deg) = sin(2.5 deg): n_i . N_g below this at a 5 deg crease
GENERATOR = "prismbake examples/make_examples.py"


# --------------------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------------------
def out_path(*parts: str) -> str:
    p = os.path.join(HERE, *parts)
    os.makedirs(os.path.dirname(p), exist_ok=True)
    return p


def normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n == 0, 1, n)


def face_normals(pos: np.ndarray, tris: np.ndarray) -> np.ndarray:
    a, b, c = pos[tris[:, 0]], pos[tris[:, 1]], pos[tris[:, 2]]
    return np.cross(b - a, c - a)  # unnormalised, length = 2 * area


def signed_volume(pos: np.ndarray, tris: np.ndarray) -> float:
    a, b, c = pos[tris[:, 0]], pos[tris[:, 1]], pos[tris[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def corner_dots(pos, nrm, tris):
    """n_i . N_g for every triangle corner (N_g unit)."""
    ng = normalize(face_normals(pos, tris))
    return np.einsum("tkj,tj->tk", nrm[tris], ng)


def weld_by_position(pos: np.ndarray, decimals: int = 6):
    key = np.round(pos, decimals)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    return inv.reshape(-1)


def check_closed(welded_tris: np.ndarray, name: str) -> None:
    """Every undirected edge used by exactly two triangles, once in each direction."""
    e = np.concatenate([welded_tris[:, [0, 1]], welded_tris[:, [1, 2]], welded_tris[:, [2, 0]]])
    directed = {}
    for a, b in map(tuple, e):
        directed[(a, b)] = directed.get((a, b), 0) + 1
    bad = [k for k, n in directed.items() if n != 1 or directed.get((k[1], k[0]), 0) != 1]
    if bad:
        raise SystemExit(f"{name}: not closed/manifold by position, {len(bad)} bad directed edges, e.g. {bad[:5]}")


# --------------------------------------------------------------------------------------
# glTF 2.0 binary writer / checker (by hand: json + struct)
# --------------------------------------------------------------------------------------
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
COMPONENT_SIZE = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
TYPE_COUNT = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def pad4(b: bytes, fill: bytes = b"\0") -> bytes:
    return b + fill * ((4 - len(b) % 4) % 4)


def write_glb(path: str, *, name: str, pos, nrm, uv_gltf, tris, index_type: int,
              camera: dict | None = None, extras: dict | None = None,
              texture: dict | None = None) -> None:
    """texture = {"name": ..., "png": bytes}: embed the PNG in the BIN chunk (a bufferView
    with no target) and use it as the material's base-colour texture (TEXCOORD_0, linear
    filtering with mipmaps, repeat); the colour factor is then 1. Without it, the material
    is a plain 0.8 grey and the file is as before."""
    pos = np.asarray(pos, np.float32)
    nrm = np.asarray(nrm, np.float32)
    uv_gltf = np.asarray(uv_gltf, np.float32)
    idx = np.asarray(tris, np.uint16 if index_type == UNSIGNED_SHORT else np.uint32).reshape(-1)
    if index_type == UNSIGNED_SHORT:
        assert len(pos) < 65535
    bin_data = b""
    views, accessors = [], []

    def add(arr: np.ndarray, target: int, comp: int, typ: str, minmax: bool = False) -> int:
        nonlocal bin_data
        off = len(bin_data)
        raw = arr.astype("<" + arr.dtype.str[1:], copy=False).tobytes()
        bin_data = pad4(bin_data + raw)
        views.append({"buffer": 0, "byteOffset": off, "byteLength": len(raw), "target": target})
        acc = {"bufferView": len(views) - 1, "byteOffset": 0, "componentType": comp,
               "count": int(arr.shape[0]), "type": typ}
        if minmax:
            acc["min"] = [float(x) for x in arr.min(axis=0)]
            acc["max"] = [float(x) for x in arr.max(axis=0)]
        accessors.append(acc)
        return len(accessors) - 1

    a_pos = add(pos, ARRAY_BUFFER, FLOAT, "VEC3", minmax=True)
    a_nrm = add(nrm, ARRAY_BUFFER, FLOAT, "VEC3")
    a_uv = add(uv_gltf, ARRAY_BUFFER, FLOAT, "VEC2")
    a_idx = add(idx, ELEMENT_ARRAY_BUFFER, index_type, "SCALAR")
    if texture is not None:
        png = bytes(texture["png"])
        off = len(bin_data)
        bin_data = pad4(bin_data + png)
        views.append({"buffer": 0, "byteOffset": off, "byteLength": len(png)})  # image: no target
        v_img = len(views) - 1
        pbr = {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "baseColorTexture": {"index": 0, "texCoord": 0},
               "metallicFactor": 0.0, "roughnessFactor": 0.7}
    else:
        pbr = {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.7}

    doc = {
        "asset": {"version": "2.0", "generator": GENERATOR,
                  "copyright": "CC0 1.0 / public domain (procedurally generated)"},
        "scene": 0,
        "scenes": [{"name": name, "nodes": [0] + ([1] if camera else [])}],
        "nodes": [{"name": name, "mesh": 0}],
        "meshes": [{"name": name, "primitives": [{
            "attributes": {"POSITION": a_pos, "NORMAL": a_nrm, "TEXCOORD_0": a_uv},
            "indices": a_idx, "mode": 4, "material": 0}]}],
        "materials": [{"name": name + "_mat", "pbrMetallicRoughness": pbr}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(bin_data)}],
    }
    if texture is not None:
        doc["images"] = [{"name": texture["name"], "bufferView": v_img, "mimeType": "image/png"}]
        doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
        doc["textures"] = [{"sampler": 0, "source": 0}]
    if extras:
        doc["meshes"][0]["extras"] = extras
    if camera:
        doc["nodes"].append({"name": "Camera", "camera": 0,
                             "translation": camera["translation"], "rotation": camera["rotation"]})
        doc["cameras"] = [{"name": "Camera", "type": "perspective", "perspective": camera["perspective"]}]

    json_bytes = pad4(json.dumps(doc, separators=(",", ":"), sort_keys=False).encode(), b" ")
    total = 12 + 8 + len(json_bytes) + 8 + len(bin_data)
    with open(path, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, total))
        f.write(struct.pack("<I4s", len(json_bytes), b"JSON"))
        f.write(json_bytes)
        f.write(struct.pack("<I4s", len(bin_data), b"BIN\0"))
        f.write(bin_data)


def glb_chunks(path: str):
    """Parse and structurally check a GLB's header, chunks and bufferViews; return (json, BIN)."""
    data = open(path, "rb").read()
    magic, version, total = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF" and version == 2, "bad header"
    assert total == len(data), f"header length {total} != file length {len(data)}"
    off = 12
    chunks = []
    while off < len(data):
        assert off % 4 == 0, "chunk not 4-byte aligned"
        clen, ctype = struct.unpack_from("<I4s", data, off)
        assert clen % 4 == 0, f"chunk {ctype} length {clen} not a multiple of 4"
        chunks.append((ctype, data[off + 8: off + 8 + clen]))
        off += 8 + clen
    assert off == len(data), "trailing bytes"
    assert chunks[0][0] == b"JSON" and chunks[1][0] == b"BIN\0", "chunk order"
    doc = json.loads(chunks[0][1].decode())
    binc = chunks[1][1]
    assert doc["asset"]["version"] == "2.0"
    assert doc["buffers"][0]["byteLength"] <= len(binc) <= doc["buffers"][0]["byteLength"] + 3
    for v in doc["bufferViews"]:
        assert v["byteOffset"] % 4 == 0, "bufferView not aligned"
        assert v["byteOffset"] + v["byteLength"] <= doc["buffers"][v["buffer"]]["byteLength"]
    for im in doc.get("images", []):
        assert "uri" not in im and im["mimeType"] in ("image/png", "image/jpeg"), im
        assert "target" not in doc["bufferViews"][im["bufferView"]], "image bufferView has a target"
        assert all(doc["accessors"][a]["bufferView"] != im["bufferView"] for a in range(len(doc["accessors"])))
    for tex in doc.get("textures", []):
        assert tex["source"] < len(doc["images"]), tex
        assert "sampler" not in tex or tex["sampler"] < len(doc["samplers"]), tex
    for m in doc.get("materials", []):
        t = m.get("pbrMetallicRoughness", {}).get("baseColorTexture")
        assert t is None or t["index"] < len(doc["textures"]), m
    return doc, binc


def glb_view_bytes(doc: dict, binc: bytes, view: int) -> bytes:
    v = doc["bufferViews"][view]
    return binc[v.get("byteOffset", 0): v.get("byteOffset", 0) + v["byteLength"]]


def read_glb(path: str):
    """Parse and structurally check a GLB; return (json, positions, normals, uvs, tris)."""
    doc, binc = glb_chunks(path)

    def accessor(i):
        a = doc["accessors"][i]
        v = doc["bufferViews"][a["bufferView"]]
        cs = COMPONENT_SIZE[a["componentType"]]
        n = TYPE_COUNT[a["type"]]
        start = v["byteOffset"] + a.get("byteOffset", 0)
        assert start % cs == 0 and a.get("byteOffset", 0) % cs == 0, "accessor misaligned"
        stride = v.get("byteStride", cs * n)
        assert stride == cs * n
        assert a.get("byteOffset", 0) + stride * (a["count"] - 1) + cs * n <= v["byteLength"], "accessor overruns view"
        dt = {5126: "<f4", 5123: "<u2", 5125: "<u4", 5121: "u1"}[a["componentType"]]
        arr = np.frombuffer(binc, dtype=dt, count=a["count"] * n, offset=start)
        return a, arr.reshape(a["count"], n) if n > 1 else arr

    prim = doc["meshes"][0]["primitives"][0]
    apos, P = accessor(prim["attributes"]["POSITION"])
    assert np.allclose(apos["min"], P.min(0)) and np.allclose(apos["max"], P.max(0)), "POSITION min/max"
    _, N = accessor(prim["attributes"]["NORMAL"])
    _, UV = accessor(prim["attributes"]["TEXCOORD_0"])
    _, I = accessor(prim["indices"])
    assert I.max() < len(P) and len(I) % 3 == 0
    return doc, P.astype(np.float64), N.astype(np.float64), UV.astype(np.float64), I.reshape(-1, 3).astype(np.int64)


def look_at_quaternion(eye, target, up=(0.0, 1.0, 0.0)):
    """Rotation (x, y, z, w) that turns a glTF camera (looking down local -Z, +Y up) toward target."""
    eye, target, up = map(lambda a: np.asarray(a, float), (eye, target, up))
    z = normalize(eye - target)                 # camera +Z points away from the target
    x = normalize(np.cross(up, z))
    y = np.cross(z, x)
    m = np.stack([x, y, z], axis=1)             # columns = camera axes in world space
    tr = np.trace(m)
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        w, qx, qy, qz = 0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
    else:  # not needed for the cameras here
        raise ValueError("camera rotation too large for this simple converter")
    q = np.array([qx, qy, qz, w])
    return q / np.linalg.norm(q), m


def quat_rotate(q, v):
    x, y, z, w = q
    u = np.array([x, y, z])
    return 2 * np.dot(u, v) * u + (w * w - np.dot(u, u)) * np.asarray(v) + 2 * w * np.cross(u, v)


# --------------------------------------------------------------------------------------
# 1. sphere.glb
# --------------------------------------------------------------------------------------
def make_sphere():
    segs, rings = 32, 16
    pos, uv = [], []
    for i in range(rings + 1):                 # i = 0: north pole row (+Y), i = rings: south pole
        th = math.pi * i / rings
        for j in range(segs + 1):              # j = segs: seam column duplicating j = 0
            u = j / segs
            if i in (0, rings):
                u = (j + 0.5) / segs           # pole rows: one vertex per fan triangle, u at its centre
            ph = 2 * math.pi * (j / segs)
            p = (math.sin(th) * math.sin(ph), math.cos(th), math.sin(th) * math.cos(ph))
            if i in (0, rings):
                p = (0.0, math.cos(th), 0.0)
            pos.append(p)
            v_up = 1.0 - i / rings             # image top row (v_up = 1) at the north pole
            uv.append((u, 1.0 - v_up))         # glTF: v points down the image
    pos = np.array(pos)
    nrm = normalize(pos)                       # radius 1: the normal is the position
    row = lambda i, j: i * (segs + 1) + j
    tris = []
    for i in range(rings):
        for j in range(segs):
            a, b, c, d = row(i, j), row(i, j + 1), row(i + 1, j), row(i + 1, j + 1)
            # phi grows toward +X seen from +Z, theta grows downward: the quad a-c-d-b is CCW
            # from outside. Pole fans use the pole vertex of column j (u at the column centre).
            if i == 0:
                tris.append((a, c, d))
            elif i == rings - 1:
                tris.append((a, c, b))
            else:
                tris.append((a, c, b))
                tris.append((b, c, d))
    tris = np.array(tris)
    # drop the unused pole vertex of the seam column (j = segs in the pole rows)
    used = np.unique(tris)
    remap = np.full(len(pos), -1)
    remap[used] = np.arange(len(used))
    pos, uv, tris = pos[used], np.array(uv)[used], remap[tris]
    nrm = nrm[used]
    # orientation: fix the per-triangle order if the analytic guess was wrong
    d = corner_dots(pos, nrm, tris)
    assert (d > 0).all(), "sphere winding"

    eye = (0.0, 1.5, 4.0)
    q, m = look_at_quaternion(eye, (0, 0, 0))
    fwd = quat_rotate(q, (0, 0, -1))
    assert np.allclose(fwd, normalize(-np.array(eye))), fwd
    camera = {"translation": list(eye), "rotation": [float(x) for x in q],
              "perspective": {"yfov": math.radians(40.0), "znear": 0.05, "zfar": 100.0}}
    path = out_path("sphere", "sphere.glb")
    write_glb(path, name="sphere", pos=pos, nrm=nrm, uv_gltf=uv, tris=tris,
              index_type=UNSIGNED_SHORT, camera=camera)
    # re-read and check
    doc, P, N, UV, T = read_glb(path)
    check_common(path, P, N, T, expect_positive=True)
    check_closed(weld_by_position(P)[T], path)
    # image top row (v_gltf = 0) is the north pole
    top = P[np.isclose(UV[:, 1], 0.0)]
    assert len(top) == 32 and np.allclose(top, [0, 1, 0], atol=1e-6)
    assert UV.min() >= 0.0 and UV.max() <= 1.0
    print(f"sphere.glb: {len(P)} vertices, {len(T)} triangles, camera q={np.round(q, 5).tolist()}")
    return len(P), len(T)


def check_common(name, P, N, T, expect_positive):
    ln = np.linalg.norm(N, axis=1)
    assert np.allclose(ln, 1.0, atol=1e-5), f"{name}: normals not unit ({ln.min()}..{ln.max()})"
    area = np.linalg.norm(face_normals(P, T), axis=1) / 2
    assert area.min() > 1e-7, f"{name}: degenerate triangle"
    assert signed_volume(P, T) > 0, f"{name}: inside-out"
    if expect_positive:
        d = corner_dots(P, N, T)
        assert d.min() > 0, f"{name}: n.Ng <= 0 somewhere ({d.min()})"


# --------------------------------------------------------------------------------------
# 2. torus.obj
# --------------------------------------------------------------------------------------
def make_torus():
    R, r, nu, nv = 1.0, 0.35, 48, 24
    u_repeat = 3  # u in [0, 3]: roughly square texels (2*pi*R / 2*pi*r ~ 2.9); needs wrap = repeat
    pos, nrm = [], []
    for i in range(nu):
        a = 2 * math.pi * i / nu
        for j in range(nv):
            b = 2 * math.pi * j / nv           # b = 0 on the outer equator, pi/2 on top
            n = (math.cos(b) * math.cos(a), math.sin(b), -math.cos(b) * math.sin(a))
            c = (R * math.cos(a), 0.0, -R * math.sin(a))
            pos.append(tuple(c[k] + r * n[k] for k in range(3)))
            nrm.append(n)
    pos, nrm = np.array(pos), np.array(nrm)
    P = lambda i, j: (i % nu) * nv + (j % nv)          # shared positions / normals (0-based)
    VT = lambda i, j: i * (nv + 1) + j                  # vt with duplicated seam row/column
    vts = [(u_repeat * i / nu, j / nv) for i in range(nu + 1) for j in range(nv + 1)]
    outer, inner = [], []
    for i in range(nu):
        for j in range(nv):
            quad = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
            bc = 2 * math.pi * (j + 0.5) / nv
            (outer if math.cos(bc) > 0 else inner).append(quad)
    # winding check on the quads' two triangles: (a, b, c) with b = +u, c = +u+v
    tri_check = []
    for q in outer + inner:
        ids = [P(*x) for x in q]
        tri_check += [(ids[0], ids[1], ids[2]), (ids[0], ids[2], ids[3])]
    tri_check = np.array(tri_check)
    d = corner_dots(pos, nrm, tri_check)
    if d.min() <= 0:  # flip if the analytic parameterisation is clockwise
        outer = [q[::-1] for q in outer]
        inner = [q[::-1] for q in inner]
    path = out_path("torus", "torus.obj")
    with open(path, "w", newline="\n") as f:
        f.write("# torus R=1 r=0.35, 48x24 quads, Y-up; generated by examples/make_examples.py (CC0)\n")
        f.write("# vt: u = 3 * major angle / 2pi (repeat), v = minor angle / 2pi, v points UP the image\n")
        f.write(f"o torus\n")
        for p in pos:
            f.write("v {:.6f} {:.6f} {:.6f}\n".format(*p))
        for t in vts:
            f.write("vt {:.6f} {:.6f}\n".format(*t))
        for n in nrm:
            f.write("vn {:.6f} {:.6f} {:.6f}\n".format(*n))
        f.write("s 1\n")
        for gname, quads in (("outer", outer), ("inner", inner)):
            f.write(f"g {gname}\n")
            for q in quads:
                f.write("f " + " ".join(f"{P(*x) + 1}/{VT(*x) + 1}/{P(*x) + 1}" for x in q) + "\n")
    # re-read (minimal OBJ parser) and check
    V, VN, F = [], [], []
    for line in open(path):
        s = line.split()
        if not s:
            continue
        if s[0] == "v":
            V.append([float(x) for x in s[1:4]])
        elif s[0] == "vn":
            VN.append([float(x) for x in s[1:4]])
        elif s[0] == "f":
            F.append([tuple(int(y) - 1 for y in x.split("/")) for x in s[1:]])
    V, VN = np.array(V), np.array(VN)
    T = np.array([(f[0][0], f[k][0], f[k + 1][0]) for f in F for k in (1, 2)])
    NT = np.array([(f[0][2], f[k][2], f[k + 1][2]) for f in F for k in (1, 2)])
    VN = normalize(VN)  # 6-decimal text: renormalise before the dot test
    ng = normalize(face_normals(V, T))
    d = np.einsum("tkj,tj->tk", VN[NT], ng)
    assert d.min() > 0, d.min()
    assert signed_volume(V, T) > 0
    check_closed(T, path)
    assert np.allclose(np.linalg.norm(np.array([[float(x) for x in l.split()[1:]] for l in open(path) if l.startswith("vn ")]), axis=1), 1, atol=2e-6)
    print(f"torus.obj: {len(V)} positions, {len(vts)} vt, {len(VN)} vn, {len(F)} quads "
          f"({len(outer)} outer + {len(inner)} inner) = {len(T)} triangles")
    return len(V), len(F), len(T)


# --------------------------------------------------------------------------------------
# 3. rock.glb: irregular closed mesh, box-projected UV islands, a knife-edge fin (creases
#    with smooth shared normals) and a hard edge loop around a flat bottom
# --------------------------------------------------------------------------------------
def make_rock(albedo):
    """albedo = (image, PNG bytes) from make_rock_albedo: embedded as the base-colour texture."""
    rng = np.random.default_rng(20250301)
    nlon = 32
    delta = math.radians(0.6)                     # half-thickness (angle) of the fin's base
    lats = [15, 35, 55, 75, None, 90, None, 105, 125, 145]
    lat_rad = []
    for k, l in enumerate(lats):
        if l is None:
            lat_rad.append(math.pi / 2 + (-delta if k < 5 else delta))
        else:
            lat_rad.append(math.radians(l))
    rim_ring = lats.index(90)
    bottom_ring = len(lats) - 1

    # smooth irregular radius: a few random plane waves over the sphere
    waves = []
    for k in range(9):
        w = normalize(rng.normal(size=3))
        lo, hi = (1.2, 2.2) if k < 4 else (2.5, 4.5)
        waves.append((w, rng.uniform(lo, hi), rng.uniform(0, 2 * math.pi),
                       rng.uniform(0.06, 0.10) if k < 4 else rng.uniform(0.02, 0.04)))

    def radius(d):
        return 1.0 + sum(a * math.sin(f * float(np.dot(w, d)) + ph) for w, f, ph, a in waves)

    phi0 = rng.uniform(0, 2 * math.pi)            # fin centre longitude

    def fin(ph):
        c = math.cos(ph - phi0)
        return 0.10 + 0.55 * max(0.0, c) ** 2

    aniso = np.array([1.18, 0.92, 0.97])
    pos = [np.array([0.0, 1.0, 0.0]) * radius(np.array([0.0, 1.0, 0.0]))]   # north pole
    for k, th in enumerate(lat_rad):
        for j in range(nlon):
            ph = 2 * math.pi * j / nlon
            d = np.array([math.sin(th) * math.sin(ph), math.cos(th), math.sin(th) * math.cos(ph)])
            dd = d if lats[k] is not None else np.array([math.sin(ph), 0.0, math.cos(ph)])
            rr = radius(dd) + (fin(ph) if k == rim_ring else 0.0)
            pos.append(d * rr)
    pos.append(np.array([0.0, -1.0, 0.0]))        # south pole (centre of the flat bottom, set below)
    pos = np.array(pos) * aniso
    y_floor = round(float(pos[1 + (bottom_ring - 1) * nlon:1 + bottom_ring * nlon, 1].min()) - 0.15, 3)
    first = lambda k: 1 + k * nlon
    ring = lambda k, j: first(k) + (j % nlon)
    south = len(pos) - 1
    # flat bottom: the last ring is projected onto y = y_floor along y
    for j in range(nlon):
        pos[ring(bottom_ring, j), 1] = y_floor
    pos[south] = [0.0, y_floor, 0.0]
    assert pos[first(bottom_ring - 1):first(bottom_ring), 1].min() > y_floor + 0.05
    # affine shear (keeps the bottom planar): tilts the fin and leans the rock
    shear = np.array([[1.0, 0.12, 0.0], [0.16, 1.0, -0.10], [0.0, 0.05, 1.0]])
    pos = pos @ shear.T

    tris, group = [], []                          # group 0 = smooth body, 1 = flat bottom
    for j in range(nlon):
        tris.append((0, ring(0, j), ring(0, j + 1))); group.append(0)
    for k in range(len(lats) - 1):
        for j in range(nlon):
            a, b, c, d = ring(k, j), ring(k, j + 1), ring(k + 1, j), ring(k + 1, j + 1)
            tris.append((a, c, d)); group.append(0)
            tris.append((a, d, b)); group.append(0)
    for j in range(nlon):
        tris.append((south, ring(bottom_ring, j + 1), ring(bottom_ring, j))); group.append(1)
    tris, group = np.array(tris), np.array(group)
    if signed_volume(pos, tris) < 0:
        tris = tris[:, ::-1]
    check_closed(tris, "rock (welded)")

    fn = face_normals(pos, tris)
    fnu = normalize(fn)
    # angle-weighted vertex normals per (position, smoothing group)
    acc = np.zeros((2, len(pos), 3))
    for t, g, n in zip(tris, group, fnu):
        for c in range(3):
            p0, p1, p2 = pos[t[c]], pos[t[(c + 1) % 3]], pos[t[(c + 2) % 3]]
            e1, e2 = normalize(p1 - p0), normalize(p2 - p0)
            ang = math.acos(max(-1.0, min(1.0, float(np.dot(e1, e2)))))
            acc[g, t[c]] += ang * n
    vnorm = normalize(acc)

    # box projection: island = dominant axis of the face normal
    ax = np.abs(fnu).argmax(1)
    sign = np.sign(fnu[np.arange(len(fnu)), ax])
    island = ax * 2 + (sign < 0)                  # 0:+X 1:-X 2:+Y 3:-Y 4:+Z 5:-Z
    E = float(np.abs(pos).max()) * 1.001
    cell, margin = 1.0 / 3.0, 0.03

    def proj(p, isl):
        x, y, z = p
        s, t = {0: (-z, y), 1: (z, y), 2: (x, -z), 3: (x, z), 4: (x, y), 5: (-x, y)}[int(isl)]
        col, row = isl % 3, isl // 3
        su, sv = (s + E) / (2 * E), (t + E) / (2 * E)
        u = col * cell + cell * (margin + (1 - 2 * margin) * su)
        v_up = 1.0 - (row * cell + cell * (margin + (1 - 2 * margin) * (1 - sv)))  # rows from the top
        return u, v_up

    vmap, V, N, UVg, T = {}, [], [], [], []
    for t, g, isl in zip(tris, group, island):
        out = []
        for pi in t:
            key = (int(pi), int(isl), int(g))
            if key not in vmap:
                vmap[key] = len(V)
                V.append(pos[pi]); N.append(vnorm[g, pi])
                u, v_up = proj(pos[pi], isl)
                UVg.append((u, 1.0 - v_up))
            out.append(vmap[key])
        T.append(out)
    V, N, UVg, T = np.array(V), np.array(N), np.array(UVg), np.array(T)

    path = out_path("rock", "rock.glb")
    albedo_img, albedo_png = albedo
    write_glb(path, name="rock", pos=V, nrm=N, uv_gltf=UVg, tris=T, index_type=UNSIGNED_INT,
              texture={"name": "rock_albedo", "png": albedo_png})
    doc, P, NN, UV, TT = read_glb(path)
    # the embedded base-colour texture: indices, sampler, and the PNG decodes to the albedo
    mat = doc["materials"][doc["meshes"][0]["primitives"][0]["material"]]["pbrMetallicRoughness"]
    assert mat == {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "baseColorTexture": {"index": 0, "texCoord": 0},
                   "metallicFactor": 0.0, "roughnessFactor": 0.7}, mat
    assert doc["textures"] == [{"sampler": 0, "source": 0}], doc["textures"]
    assert doc["samplers"] == [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    (image,) = doc["images"]
    assert image["name"] == "rock_albedo" and image["mimeType"] == "image/png", image
    view = doc["bufferViews"][image["bufferView"]]
    assert "target" not in view and view["byteOffset"] % 4 == 0, view
    _, binc = glb_chunks(path)
    embedded = glb_view_bytes(doc, binc, image["bufferView"])
    assert embedded == albedo_png == open(out_path("maps", "rock_albedo_256.png"), "rb").read()
    assert np.array_equal(decode_png(embedded), albedo_img)
    check_common(path, P, NN, TT, expect_positive=False)
    assert corner_dots(P, NN, TT).min() > 0, "rock: folded or inverted corner"
    welded = weld_by_position(P)
    check_closed(welded[TT], path)

    # statistics: creases, hard edges, seams
    d = corner_dots(P, NN, TT)
    n_crease_corners = int((d < CREASE_COS).sum())
    # dihedral angles over welded edges
    fnn = normalize(face_normals(P, TT))
    edge_faces = {}
    for f, t in enumerate(welded[TT]):
        for c in range(3):
            a, b = int(t[c]), int(t[(c + 1) % 3])
            edge_faces.setdefault((min(a, b), max(a, b)), []).append((f, c))
    sharp, hard, seam = 0, 0, 0
    for (a, b), fl in edge_faces.items():
        (f0, c0), (f1, c1) = fl
        interior = 180.0 - math.degrees(math.acos(max(-1, min(1, float(np.dot(fnn[f0], fnn[f1]))))))
        sharp += interior < 5.0
        # per-face vertex ids at the edge's endpoints
        def ends(f, c):
            return {int(welded[TT[f, c]]): int(TT[f, c]), int(welded[TT[f, (c + 1) % 3]]): int(TT[f, (c + 1) % 3])}
        e0, e1 = ends(f0, c0), ends(f1, c1)
        if any(not np.allclose(NN[e0[w]], NN[e1[w]], atol=1e-6) for w in (a, b)):
            hard += 1
        elif any(not np.allclose(UV[e0[w]], UV[e1[w]], atol=1e-7) for w in (a, b)):
            seam += 1
    print(f"rock.glb: {len(P)} vertices ({welded.max() + 1} distinct positions), {len(TT)} triangles, "
          f"{len(edge_faces)} edges; {sharp} edges with interior dihedral < 5 deg; "
          f"{hard} hard edges (split normals); {seam} UV-seam-only edges; 6 box-projection islands")
    print(f"rock.glb: {n_crease_corners} triangle corners with n_i.N_g < {CREASE_COS} "
          f"(min n_i.N_g = {d.min():.4f}, {int((d <= 0).sum())} corners <= 0)")
    if n_crease_corners < 6 or sharp < 4 or hard < 3:
        raise SystemExit("rock: not enough creases / hard edges")
    return len(P), len(TT), n_crease_corners, sharp, hard


# --------------------------------------------------------------------------------------
# 4. height maps (tileable: every lattice is periodic in the image size)
# --------------------------------------------------------------------------------------
def value_noise(n: int, period: int, rng) -> np.ndarray:
    """Tileable value noise on an n x n image with a period x period random lattice (quintic fade)."""
    lat = rng.random((period, period))
    t = (np.arange(n) + 0.5) * period / n
    i0 = np.floor(t).astype(int)
    f = t - i0
    f = f * f * f * (f * (f * 6 - 15) + 10)
    i0 %= period
    i1 = (i0 + 1) % period
    a = lat[np.ix_(i0, i0)] * (1 - f)[None, :] + lat[np.ix_(i0, i1)] * f[None, :]
    b = lat[np.ix_(i1, i0)] * (1 - f)[None, :] + lat[np.ix_(i1, i1)] * f[None, :]
    return a * (1 - f)[:, None] + b * f[:, None]


def fbm(n, base_period, octaves, rng, gain=0.5):
    out, amp, tot = np.zeros((n, n)), 1.0, 0.0
    for o in range(octaves):
        out += amp * value_noise(n, base_period * 2 ** o, rng)
        tot += amp
        amp *= gain
    return out / tot


def worley(n, cells, rng, second=False):
    """Tileable cellular noise: distances (in cell units) to jittered points on a periodic grid."""
    pts = rng.random((cells, cells, 2))
    t = (np.arange(n) + 0.5) * cells / n
    Y, X = np.meshgrid(t, t, indexing="ij")
    ci, cj = np.floor(Y).astype(int), np.floor(X).astype(int)
    best = np.full((2, n, n), np.inf)
    ids = np.zeros((n, n), int)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            gi, gj = ci + di, cj + dj
            p = pts[gi % cells, gj % cells]
            d = np.hypot(gi + p[..., 0] - Y, gj + p[..., 1] - X)
            cid = (gi % cells) * cells + (gj % cells)
            closer = d < best[0]
            best[1] = np.where(closer, best[0], np.minimum(best[1], d))
            ids = np.where(closer, cid, ids)
            best[0] = np.where(closer, d, best[0])
    return best, ids


def stretch(h, lo=0.02, hi=0.98):
    a, b = np.percentile(h, 0.05), np.percentile(h, 99.95)
    return np.clip(lo + (hi - lo) * (h - a) / (b - a), 0.0, 1.0)


def encode_png(img: np.ndarray, bits: int) -> bytes:
    """PNG bytes (zlib + struct): grayscale (h, w) at 8 or 16 bit, or RGB (h, w, 3) at 8 bit.
    Per-row filter = best of None/Sub/Up; no interlace; Software and Copyright tEXt chunks."""
    h, w = img.shape[:2]
    channels = 1 if img.ndim == 2 else img.shape[2]
    assert channels in (1, 3) and (channels == 1 or bits == 8), (img.shape, bits)
    if bits == 16:
        raw = img.astype(">u2").view(np.uint8).reshape(h, w * 2)
        bpp = 2
    else:
        raw = img.astype(np.uint8).reshape(h, w * channels)
        bpp = channels
    raw = raw.astype(np.int16)
    rows = []
    prev = np.zeros(raw.shape[1], np.int16)
    for y in range(h):
        cur = raw[y]
        sub = cur.copy(); sub[bpp:] = cur[bpp:] - cur[:-bpp]
        up = cur - prev
        cands = [(0, cur), (1, sub % 256), (2, up % 256)]
        score = lambda a: int(np.abs(np.where(a > 127, a - 256, a)).sum())
        ft, data = min(cands, key=lambda c: score(c[1]))
        rows.append(bytes([ft]) + data.astype(np.uint8).tobytes())
        prev = cur
    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    colour_type = 0 if channels == 1 else 2
    png = b"\x89PNG\r\n\x1a\n"
    png += chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bits, colour_type, 0, 0, 0))
    png += chunk(b"tEXt", b"Software\0" + GENERATOR.encode())
    png += chunk(b"tEXt", b"Copyright\0CC0 1.0 / public domain (procedurally generated)")
    png += chunk(b"IDAT", zlib.compress(b"".join(rows), 9))
    png += chunk(b"IEND", b"")
    return png


def write_png(path: str, img: np.ndarray, bits: int) -> bytes:
    """Write `encode_png(img, bits)` to path; return the bytes written."""
    png = encode_png(img, bits)
    with open(path, "wb") as f:
        f.write(png)
    return png


def decode_png(data: bytes) -> np.ndarray:
    """Inverse of encode_png (filters None/Sub/Up only): (h, w) for grey, (h, w, 3) for RGB."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    off, idat, hdr = 8, b"", None
    while off < len(data):
        ln, tag = struct.unpack_from(">I4s", data, off)
        body = data[off + 8: off + 8 + ln]
        assert struct.unpack_from(">I", data, off + 8 + ln)[0] == zlib.crc32(tag + body) & 0xFFFFFFFF
        if tag == b"IHDR":
            hdr = struct.unpack(">IIBBBBB", body)
        elif tag == b"IDAT":
            idat += body
        off += 12 + ln
    assert off == len(data), "trailing bytes after IEND"
    w, h, bits, ctype, _, _, interlace = hdr
    assert ctype in (0, 2) and interlace == 0 and (ctype == 0 or bits == 8), hdr
    channels = 1 if ctype == 0 else 3
    bpp = bits // 8 * channels
    raw = zlib.decompress(idat)
    stride = w * bpp
    assert len(raw) == h * (stride + 1)
    out = np.zeros((h, stride), np.int32)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        ft = raw[y * (stride + 1)]
        cur = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int32)
        if ft == 1:
            for k in range(bpp):  # cumulative sum per byte lane, mod 256
                cur[k::bpp] = np.cumsum(cur[k::bpp]) % 256
        elif ft == 2:
            cur = (cur + prev) % 256
        else:
            assert ft == 0, ft
        out[y] = cur
        prev = cur
    if bits == 16:
        return (out[:, 0::2] * 256 + out[:, 1::2]).astype(np.uint16)
    if channels == 3:
        return out.reshape(h, w, 3).astype(np.uint8)
    return out.astype(np.uint8)


def read_png(path: str) -> np.ndarray:
    with open(path, "rb") as f:
        return decode_png(f.read())


def tile_check(name, img):
    """Wrap-around differences must look like interior ones (tileable)."""
    f = img.astype(np.float64)
    inner = np.abs(np.diff(f, axis=1)).mean()
    wrap = np.abs(f[:, 0] - f[:, -1]).mean()
    inner_v = np.abs(np.diff(f, axis=0)).mean()
    wrap_v = np.abs(f[0] - f[-1]).mean()
    assert wrap < 2.5 * inner and wrap_v < 2.5 * inner_v, (name, inner, wrap, inner_v, wrap_v)


def make_maps():
    # rock_1024.png: fBm + cellular plates, 16-bit
    n = 1024
    rng = np.random.default_rng(1024)
    base = fbm(n, 4, 7, rng, gain=0.55)
    (f1, f2), _ = worley(n, 12, rng)
    cracks = np.clip((f2 - f1) / 0.25, 0, 1) ** 0.6          # 0 in the cracks between plates
    domes = 1.0 - np.clip(f1 / 0.9, 0, 1) ** 2
    grit = fbm(n, 64, 3, rng)
    h = 0.55 * base + 0.25 * domes * cracks + 0.15 * cracks + 0.05 * grit
    h = stretch(h)
    # Fade to the midlevel at the top and bottom rows: on the sphere those rows collapse into
    # the poles, where a varying height would tear the displaced surface open (every pole
    # copy of the vertex would sample a different texel).
    rows = np.arange(n) + 0.5
    edge = np.minimum(rows, n - rows) / 24.0
    fade = np.clip(edge - 0.5, 0.0, 1.0)
    fade = (fade * fade * (3.0 - 2.0 * fade))[:, None]
    h = 0.5 + (h - 0.5) * fade
    img16 = np.round(h * 65535).astype(np.uint16)
    p = out_path("maps", "rock_1024.png")
    write_png(p, img16, 16)
    back = read_png(p)
    assert np.array_equal(back, img16)
    tile_check(p, img16)
    print(f"rock_1024.png: 16-bit {n}x{n}, h in [{h.min():.3f}, {h.max():.3f}], mean {h.mean():.3f}")

    # bumps_512.exr: smooth bumps + ridges, float32 channel "Y"
    n = 512
    rng = np.random.default_rng(512)
    t = (np.arange(n) + 0.5) / n
    Y, X = np.meshgrid(t, t, indexing="ij")
    bumps = np.zeros((n, n))
    for _ in range(40):
        cy, cx = rng.random(2)
        s = rng.uniform(0.03, 0.09)
        amp = rng.uniform(0.4, 1.0)
        dy = (Y - cy + 0.5) % 1.0 - 0.5                       # periodic distance
        dx = (X - cx + 0.5) % 1.0 - 0.5
        bumps += amp * np.exp(-(dx * dx + dy * dy) / (2 * s * s))
    ridge = 1.0 - np.abs(2 * fbm(n, 4, 4, rng) - 1)             # ridged noise
    ridge = ridge ** 3
    h = 0.65 * bumps / bumps.max() + 0.35 * ridge
    h = (h - h.min()) / (h.max() - h.min())
    h = (0.02 + 0.96 * h).astype(np.float32)
    p = out_path("maps", "bumps_512.exr")
    write_exr_y(p, h)
    back = read_exr_y(p)
    assert back.dtype == np.float32 and np.array_equal(back, h)
    tile_check(p, h)
    print(f"bumps_512.exr: float32 Y {n}x{n}, h in [{h.min():.3f}, {h.max():.3f}], mean {h.mean():.3f}")

    # scales_256.png: overlapping fish scales (rows offset by half a scale), 8-bit
    n = 256
    rng = np.random.default_rng(256)
    sx, sy = n // 8, n // 16                                      # scale pitch in pixels (divides n)
    R = 0.62 * sx                                                 # scale radius in pixels
    Y, X = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5, indexing="ij")
    best = np.full((n, n), -1.0)
    cell = np.full((n, n), -1)                                    # which scale is on top (for the albedo)
    rows, cols = n // sy, n // sx                                 # scales per period (rows even: tiles)
    for r in range(-3, n // sy + 3):                              # rows drawn top to bottom:
        off = 0.5 * sx * (r % 2)                                  # a lower row overlaps the one above
        for c in range(-2, n // sx + 2):
            cx, cy = c * sx + off, r * sy
            d = np.hypot(X - cx, Y - cy) / R
            dome = np.sqrt(np.clip(1 - d * d, 0, 1)) * (0.6 + 0.4 * np.clip((Y - cy) / R + 0.5, 0, 1))
            best = np.where(d < 1, dome, best)
            cell = np.where(d < 1, (r % rows) * cols + c % cols, cell)   # periodic scale id
    assert (cell >= 0).all() and (best >= 0).all(), "scales leave a gap"
    best = np.where(best < 0, 0, best)
    h = 0.85 * best + 0.15 * fbm(n, 16, 3, rng)
    h = stretch(h, 0.03, 0.97)
    img8 = np.round(h * 255).astype(np.uint8)
    p = out_path("maps", "scales_256.png")
    write_png(p, img8, 8)
    back = read_png(p)
    assert np.array_equal(back, img8)
    tile_check(p, img8)
    print(f"scales_256.png: 8-bit {n}x{n}, h in [{h.min():.3f}, {h.max():.3f}], mean {h.mean():.3f}")

    return make_rock_albedo(img8, cell, rows * cols)


def srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x):
    x = np.asarray(x, np.float64)
    return np.where(x <= 0.0031308, x * 12.92, 1.055 * np.maximum(x, 0.0) ** (1 / 2.4) - 0.055)


# Earthy sRGB base colours for the rock's scales (one per scale, jittered per scale).
ROCK_PALETTE = [
    (150, 88, 58),     # rust
    (168, 128, 74),    # ochre
    (112, 84, 62),     # umber
    (118, 120, 76),    # olive
    (96, 106, 100),    # slate
    (176, 156, 120),   # sand
    (132, 100, 86),    # red-brown
]


def make_rock_albedo(h8: np.ndarray, cell: np.ndarray, ncells: int):
    """rock_albedo_256.png: 8-bit sRGB base colour for the rock, from the same data as
    scales_256.png (its 8-bit heights h8 and the id of the scale on top at each pixel), so
    colour lines up with the displaced scales at the same UVs. Each scale gets its own earthy
    colour (a palette entry, tinted and brightened per scale); low height (the grooves at a
    scale's rim) is darker, the crests lighter; a tileable fBm mottles it. Computed in
    linear light, kept in sRGB [40, 200]. Returns (image, PNG bytes)."""
    n = h8.shape[0]
    rng = np.random.default_rng(2560)
    pal = srgb_to_linear(np.array(ROCK_PALETTE) / 255.0)
    pick = rng.integers(0, len(pal), ncells)
    tint = rng.uniform(0.92, 1.08, (ncells, 3))                  # hue jitter per scale
    value = rng.uniform(0.85, 1.10, (ncells, 1))                 # brightness per scale
    base = pal[pick] * tint * value
    h = h8 / 255.0
    t = np.clip((h - 0.10) / 0.75, 0.0, 1.0)
    shade = 0.30 + 0.80 * t * t * (3 - 2 * t)                    # grooves dark, crests light
    mottle = 0.88 + 0.24 * fbm(n, 32, 3, rng)                    # tileable (periodic lattice)
    lin = base[cell] * (shade * mottle)[..., None]
    lo, hi = srgb_to_linear(40 / 255), srgb_to_linear(200 / 255)
    clipped = float(((lin < lo) | (lin > hi)).mean())          # of channel values: the bluest
    assert clipped < 0.03, clipped                               # channel in the darkest grooves
    lin = np.clip(lin, lo, hi)
    img = np.round(linear_to_srgb(lin) * 255).astype(np.uint8)
    p = out_path("maps", "rock_albedo_256.png")
    png = write_png(p, img, 8)
    back = read_png(p)
    assert back.shape == (n, n, 3) and np.array_equal(back, img)
    for k in range(3):
        tile_check(p, img[..., k])
    # colour follows the scales: chromaticity varies far more between scales than inside one,
    # and the grooves are darker than the crests
    rgb = img.reshape(-1, 3).astype(np.float64)
    chrom = rgb / rgb.sum(1, keepdims=True)
    ids = cell.reshape(-1)
    count = np.bincount(ids, minlength=ncells)[:, None]
    mean = np.stack([np.bincount(ids, chrom[:, k], ncells) for k in range(3)], 1) / count
    within = ((chrom - mean[ids]) ** 2).sum(1).mean()
    between = ((mean[ids] - chrom.mean(0)) ** 2).sum(1).mean()
    assert between > 4 * within, (between, within)
    luma = img.astype(np.float64) @ [0.2126, 0.7152, 0.0722]
    groove, crest = h8 < np.percentile(h8, 15), h8 > np.percentile(h8, 85)
    assert luma[groove].mean() < 0.75 * luma[crest].mean(), (luma[groove].mean(), luma[crest].mean())
    chroma = img.max(2).astype(np.int64) - img.min(2)
    assert chroma.mean() > 20 and chroma.std() > 10, (chroma.mean(), chroma.std())
    print(f"rock_albedo_256.png: 8-bit sRGB {n}x{n}, {ncells} scales, {len(pal)} base colours, "
          f"sRGB in [{img.min()}, {img.max()}], linear in [{lin.min():.3f}, {lin.max():.3f}] "
          f"({100 * clipped:.2f}% of values clamped), mean chroma {chroma.mean():.1f}/255, "
          f"chromaticity variance between/within scales {between / within:.1f}")
    return img, png


def write_exr_y(path: str, h: np.ndarray) -> None:
    import OpenEXR
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"Y": np.ascontiguousarray(h, np.float32)}) as f:
        f.write(path)


def read_exr_y(path: str) -> np.ndarray:
    import OpenEXR
    with OpenEXR.File(path) as f:
        ch = f.channels()
        assert list(ch.keys()) == ["Y"], list(ch.keys())
        return np.array(ch["Y"].pixels)


# --------------------------------------------------------------------------------------
# 5. sidecars
# --------------------------------------------------------------------------------------
SIDECARS = {
    ("sphere", "sphere"): ('"../maps/rock_1024.png"', 0.08, None),
    ("torus", "torus"): ('"../maps/bumps_512.exr"', 0.06, "Y"),
    ("rock", "rock"): ('"../maps/scales_256.png"', 0.05, None),
}


def make_sidecars():
    for (folder, name), (disp, scale, channel) in SIDECARS.items():
        lines = [
            "# prismbake per-asset settings (see docs/sidecar.md)",
            f"disp = {disp}   # path relative to this file",
            f"scale = {scale}",
            "midlevel = 0.5",
            'wrap = "repeat"',
        ]
        if channel:
            lines.append(f'channel = "{channel}"   # the EXR\'s single float channel')
            lines.append("# optional: uv_set = 0")
        else:
            lines.append('# optional: channel = "Y", uv_set = 0')
        with open(out_path(folder, f"{name}.prismbake.toml"), "w", newline="\n") as f:
            f.write("\n".join(lines) + "\n")


def main():
    albedo = make_maps()
    make_sphere()
    make_torus()
    make_rock(albedo)
    make_sidecars()
    total = 0
    for root, _, files in os.walk(HERE):
        for fn in sorted(files):
            if fn.endswith((".glb", ".obj", ".png", ".exr", ".toml")):
                p = os.path.join(root, fn)
                total += os.path.getsize(p)
                print(f"  {os.path.relpath(p, HERE):32s} {os.path.getsize(p):>9d} bytes")
    print(f"total {total} bytes")


if __name__ == "__main__":
    sys.exit(main())
