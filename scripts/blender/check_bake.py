"""Blender as the DCC that plays a sinew bake (`sinew bake --format pc2,glb`).

Run: blender -b --python scripts/blender/check_bake.py -- BAKE_DIR FRAME [FRAME ...]

Imports BAKE_DIR/scene.glb with Blender's own glTF importer (the scene's frame
rate set to the bake's, so Blender frame F is sinew frame F), puts a Mesh
Cache modifier on every muscle playing its .pc2 (the node's extras name it;
file axes Forward +Z, Up +Y: glTF's), and at each FRAME compares the meshes
Blender evaluates, in world space, with:

- the bake's own data: each muscle's .pc2 sample FRAME and each bone's mesh
  posed by the .glb's keys at FRAME (read here, not by Blender);
- with SINEW_EXPECTED=DIR, also sinew's positions read from DIR/FRAME.f32:
  little-endian f32 x y z in metres, glTF frame, every muscle's surface in
  muscle order then every bone mesh's world positions in bone order, as the
  test that calls this script writes them.

Prints one RESULT line per frame and exits non-zero when a vertex differs by
more than 1e-5 m, a mesh is missing, or nothing moves between the frames.
"""
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from glb_file import GlbFile, rotation_matrix  # noqa: E402

TOLERANCE = 1e-5
args = sys.argv[sys.argv.index("--") + 1:]
bake_dir, frames = args[0], [int(f) for f in args[1:]]
glb_path = os.path.join(bake_dir, "scene.glb")

glb = GlbFile(glb_path)
doc, accessor = glb.doc, glb.accessor


def read_pc2(path):
    raw = open(path, "rb").read()
    assert raw[:12] == b"POINTCACHE2\0", f"{path}: not a .pc2"
    points, _, _, samples = struct.unpack("<iffi", raw[16:32])
    return np.frombuffer(raw, dtype="<f4", offset=32).reshape(samples, points, 3)


# The bake's keys: one per frame, dt apart.
animation = (doc.get("animations") or [None])[0]
keys = {}  # (node, path) -> values per frame
dt = 1 / 60
if animation:
    for channel in animation["channels"]:
        sampler = animation["samplers"][channel["sampler"]]
        times = accessor(sampler["input"])[:, 0]
        dt = float(times[1] - times[0])
        keys[(channel["target"]["node"], channel["target"]["path"])] = accessor(sampler["output"])


def local_matrix(i, frame):
    node = doc["nodes"][i]
    t = keys.get((i, "translation"), [node.get("translation", [0, 0, 0])] * (frame + 1))[frame]
    r = keys.get((i, "rotation"), [node.get("rotation", [0, 0, 0, 1])] * (frame + 1))[frame]
    s = keys.get((i, "scale"), [node.get("scale", [1, 1, 1])] * (frame + 1))[frame]
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(np.asarray(r, dtype=np.float64)) * np.asarray(s, dtype=np.float64)
    m[:3, 3] = t
    return m


parent = {c: i for i, node in enumerate(doc["nodes"]) for c in node.get("children", [])}


def node_matrix(i, frame):
    """Node i's world matrix at `frame`: its ancestors' keys composed."""
    local = local_matrix(i, frame)
    return node_matrix(parent[i], frame) @ local if i in parent else local


muscles, bones = [], []  # (index, node)
for i, node in enumerate(doc["nodes"]):
    extras = node.get("extras", {})
    if "sinew_muscle" in extras:
        muscles.append((extras["sinew_muscle"], i))
    elif "sinew_bone" in extras and "mesh" in node:
        bones.append((extras["sinew_bone"], i))
muscles.sort()
bones.sort()
caches = {i: read_pc2(os.path.join(bake_dir, doc["nodes"][i]["extras"]["sinew_pc2"]))
          for _, i in muscles}


def bake_positions(frame):
    """World positions the bake itself says, in glTF's frame."""
    out = [caches[i][frame].astype(np.float64) for _, i in muscles]
    for _, i in bones:
        rest = accessor(doc["meshes"][doc["nodes"][i]["mesh"]]["primitives"][0]["attributes"]["POSITION"])
        homogeneous = np.hstack([rest.astype(np.float64), np.ones((len(rest), 1))])
        out.append((homogeneous @ node_matrix(i, frame).T)[:, :3])
    return np.concatenate(out)


bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
fps = max(1, round(1 / dt))
scene.render.fps, scene.render.fps_base = fps, fps * dt
bpy.ops.import_scene.gltf(filepath=glb_path)

objects = {}
for o in scene.objects:
    if o.type != "MESH":
        continue
    if "sinew_muscle" in o:
        objects[("muscle", o["sinew_muscle"])] = o
        cache = o.modifiers.new("sinew", "MESH_CACHE")
        cache.cache_format = "PC2"
        cache.filepath = os.path.join(bake_dir, o["sinew_pc2"])
        cache.forward_axis, cache.up_axis = "POS_Z", "NEG_Y"
    elif "sinew_bone" in o:
        objects[("bone", o["sinew_bone"])] = o
order = [("muscle", m) for m, _ in muscles] + [("bone", b) for b, _ in bones]
missing = [key for key in order if key not in objects]
if missing:
    sys.exit(f"RESULT: Blender has no object for {missing}")

expected_dir = os.environ.get("SINEW_EXPECTED")
failed = False
previous = None
for frame in frames:
    scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    got = []
    for key in order:
        o = objects[key]
        mesh = o.evaluated_get(depsgraph).to_mesh()
        world = np.array(o.matrix_world)
        co = np.array([tuple(v.co) for v in mesh.vertices], dtype=np.float64)
        co = np.hstack([co, np.ones((len(co), 1))]) @ world.T
        got.append(co[:, :3])
    got = np.concatenate(got)
    got = np.stack([got[:, 0], got[:, 2], -got[:, 1]], 1)  # Blender Z-up -> glTF Y-up
    bake = bake_positions(frame)
    if len(got) != len(bake):
        print(f"RESULT frame {frame}: Blender has {len(got)} vertices, the bake {len(bake)}")
        failed = True
        continue
    error = np.linalg.norm(got - bake, axis=1).max()
    ok = error <= TOLERANCE
    line = f"RESULT frame {frame}: max |Blender - bake| = {error:.2e} m"
    if expected_dir:
        sinew = np.fromfile(os.path.join(expected_dir, f"{frame}.f32"), dtype="<f4").reshape(-1, 3)
        sinew_error = np.linalg.norm(got - sinew, axis=1).max() if len(sinew) == len(got) else np.inf
        ok &= sinew_error <= TOLERANCE
        line += f", max |Blender - sinew| = {sinew_error:.2e} m"
    if previous is not None:
        moved = np.linalg.norm(got - previous, axis=1).max()
        ok &= moved > 1e-4
        line += f", moved up to {moved * 1000:.1f} mm since the last frame checked"
    previous = got
    failed |= not ok
    print(f"{line} ({len(got)} vertices, {len(muscles)} muscles, {len(bones)} bones): "
          f"{'ok' if ok else 'FAILED'}")
sys.exit(1 if failed else 0)
