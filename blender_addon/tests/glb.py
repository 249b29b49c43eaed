"""A minimal GLB reader for the tests: the triangles and positions of the first mesh."""
import json
import struct

import numpy as np

_COMPONENTS = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def read_glb(path):
    data = open(path, "rb").read()
    magic, _version, _length = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF", f"{path} is not a GLB"
    json_len, _ = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20:20 + json_len])
    bin_start = 20 + json_len + 8
    return doc, data[bin_start:]


def accessor(doc, binary, index):
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    width = _WIDTH[acc["type"]]
    arr = np.frombuffer(binary, dtype=_COMPONENTS[acc["componentType"]],
                        count=acc["count"] * width, offset=start)
    return arr.reshape(acc["count"], width) if width > 1 else arr


def triangles(path):
    """(positions (n,3), triangles (m,3)) of every primitive of the first mesh, in file order."""
    doc, binary = read_glb(path)
    pos_all, tri_all, base = [], [], 0
    for prim in doc["meshes"][0]["primitives"]:
        pos = accessor(doc, binary, prim["attributes"]["POSITION"])
        idx = accessor(doc, binary, prim["indices"]).reshape(-1, 3)
        pos_all.append(pos)
        tri_all.append(idx.astype(np.int64) + base)
        base += len(pos)
    return np.concatenate(pos_all), np.concatenate(tri_all), doc
