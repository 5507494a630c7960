"""Reading a .glb without Blender, for the checks that compare Blender's
import with the file: the JSON document, accessors as NumPy arrays, and
glTF's quaternion-to-matrix. Also makes Debian's Blender 3.4 glTF importer
work with NumPy >= 1.24 (it still uses `np.bool`)."""
import json
import struct

import numpy as np

if not hasattr(np, "bool"):
    np.bool = bool


class GlbFile:
    """A binary glTF file: `doc` (the JSON chunk) and `accessor(i)`."""

    def __init__(self, path):
        data = open(path, "rb").read()
        json_len = struct.unpack("<I", data[12:16])[0]
        self.doc = json.loads(data[20:20 + json_len])
        self.binary = data[20 + json_len + 8:]

    def accessor(self, index):
        """Accessor `index` as an array of shape (count, components)."""
        a = self.doc["accessors"][index]
        view = self.doc["bufferViews"][a["bufferView"]]
        kind = {5126: "<f4", 5123: "<u2", 5125: "<u4"}[a["componentType"]]
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a["type"]]
        return np.frombuffer(self.binary, dtype=kind, count=a["count"] * width,
                             offset=view["byteOffset"]).reshape(a["count"], width)


def rotation_matrix(q):
    """The 3x3 rotation of glTF quaternion (x, y, z, w)."""
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
