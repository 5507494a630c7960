"""Draws an OBJ written by `sinew fit --obj` (objects `skin`, `bone:NAME`,
`muscle:NAME`; metres, +Y up) into a PNG: the skin translucent, bones ivory,
muscles red, orthographic, from the front (+Z) or the side (+X).

Run (Workbench needs OpenGL: under Xvfb on a machine without a display):
  xvfb-run -a blender -b --factory-startup --python scripts/blender/render_obj.py -- FILE.obj OUT.png front|side
"""
import math
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
obj_file, png, view = args[0], args[1], args[2]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.obj(filepath=obj_file, axis_forward="-Z", axis_up="Y")
scene = bpy.context.scene
colours = {"skin": (0.8, 0.6, 0.5, 0.25), "bone": (0.9, 0.88, 0.8, 1.0), "muscle": (0.7, 0.1, 0.1, 1.0)}
for o in scene.objects:
    if o.type == "MESH":
        kind = o.name.split(":")[0].split(".")[0]
        material = bpy.data.materials.new(o.name)
        material.diffuse_color = colours.get(kind, (0.5, 0.5, 0.5, 1.0))
        o.data.materials.clear()
        o.data.materials.append(material)
camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
camera.data.type = "ORTHO"
camera.data.ortho_scale = 2.0
scene.collection.objects.link(camera)
scene.camera = camera
if view == "side":
    camera.location, camera.rotation_euler = (5, 0, 0.85), (math.pi / 2, 0, math.pi / 2)
else:
    camera.location, camera.rotation_euler = (0, -5, 0.85), (math.pi / 2, 0, 0)
scene.render.engine = "BLENDER_WORKBENCH"
scene.display.shading.color_type = "MATERIAL"
scene.render.resolution_x = scene.render.resolution_y = 500
scene.render.filepath = png
bpy.ops.render.render(write_still=True)
