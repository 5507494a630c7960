"""Blender as the DCC that reads sinew's skinned glTF characters.

Run: blender -b --python scripts/blender/check_glb.py -- FILE.glb TIME [TIME ...]

With SINEW_EXPECTED=DIR, Blender's mesh at each TIME is also compared with
sinew's own skinning, read from DIR/<TIME>.f32 (little-endian x y z per
vertex, glTF frame), as the test that calls this script writes it.

Imports FILE.glb with Blender's own glTF importer, poses it at each TIME (s,
which must be a key time of the file's first animation), and compares the
skinned mesh Blender evaluates with linear-blend skinning computed here from
the file itself (glTF's definition). Prints one RESULT line per time and exits
non-zero when a vertex differs by more than 1e-5 m, the vertex counts differ,
or the clip does not move the skin.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from glb_file import GlbFile, rotation_matrix  # noqa: E402

TOLERANCE = 1e-5
args = sys.argv[sys.argv.index("--") + 1:]
path, times = args[0], [float(t) for t in args[1:]]

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path)

glb = GlbFile(path)
doc, accessor = glb.doc, glb.accessor
attributes = doc["meshes"][0]["primitives"][0]["attributes"]
rest = accessor(attributes["POSITION"]).astype(np.float64)
joints = accessor(attributes["JOINTS_0"])
weights = accessor(attributes["WEIGHTS_0"]).astype(np.float64)
skin = doc["skins"][0]
nodes = doc["nodes"]
parent = {c: i for i, node in enumerate(nodes) for c in node.get("children", [])}
inverse_binds = accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
animation = doc["animations"][0]


def expected_at(t):
    rotations = {}
    for channel in animation["channels"]:
        sampler = animation["samplers"][channel["sampler"]]
        keys = accessor(sampler["input"])[:, 0]
        k = int(np.argmin(abs(keys - t)))
        if abs(keys[k] - t) > 1e-6:
            sys.exit(f"{t} s is not a key time of the clip")
        rotations[channel["target"]["node"]] = accessor(sampler["output"])[k].astype(np.float64)
    world = {}

    def world_of(i):
        if i not in world:
            local = np.eye(4)
            local[:3, 3] = nodes[i].get("translation", [0, 0, 0])
            if i in rotations:
                local[:3, :3] = rotation_matrix(rotations[i])
            world[i] = world_of(parent[i]) @ local if i in parent else local
        return world[i]

    matrices = np.stack([world_of(j) @ inverse_binds[k] for k, j in enumerate(skin["joints"])])
    homogeneous = np.hstack([rest, np.ones((len(rest), 1))])
    out = np.zeros_like(rest)
    for s in range(4):
        out += weights[:, s:s + 1] * np.einsum("nij,nj->ni", matrices[joints[:, s]], homogeneous)[:, :3]
    return out


scene = bpy.context.scene
fps = scene.render.fps / scene.render.fps_base
mesh_object = next(o for o in scene.objects if o.type == "MESH")
failed = False
for t in times:
    scene.frame_set(int(round(t * fps)))
    evaluated = mesh_object.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    got = np.array([tuple(mesh_object.matrix_world @ v.co) for v in evaluated.vertices])
    got = np.stack([got[:, 0], got[:, 2], -got[:, 1]], 1)  # Blender Z-up -> glTF Y-up
    if len(got) != len(rest):
        print(f"RESULT t={t}: Blender has {len(got)} vertices, the file {len(rest)}")
        failed = True
        continue
    expected = expected_at(t)
    error = np.linalg.norm(got - expected, axis=1).max()
    moved = np.linalg.norm(expected - rest, axis=1).max()
    ok = error <= TOLERANCE and (t == 0 or moved > 0.01)
    line = (f"RESULT t={t} s (frame {scene.frame_current}): max |Blender - glTF skinning| = "
            f"{error:.2e} m, skin moved up to {moved:.3f} m")
    expected_dir = os.environ.get("SINEW_EXPECTED")
    if expected_dir:
        sinew = np.fromfile(os.path.join(expected_dir, f"{args[1 + times.index(t)]}.f32"), dtype="<f4")
        sinew_error = np.linalg.norm(got - sinew.reshape(-1, 3), axis=1).max()
        ok &= sinew_error <= TOLERANCE
        line += f", max |Blender - sinew skinning| = {sinew_error:.2e} m"
    failed |= not ok
    print(f"{line}: {'ok' if ok else 'FAILED'}")
sys.exit(1 if failed else 0)
