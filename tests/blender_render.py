"""Imports a glTF file into Blender (the `bpy` module, Blender's own glTF importer) and renders it
with Cycles on the CPU: the check that a furred asset opens and draws right in Blender.

Usage: python3 tests/blender_render.py FILE.glb OUT.png TRANSPARENT_BOUNCES
The camera looks at (0, 0.6, 0) from (1.2, 1.3, 2.4) in glTF coordinates (Y up; Blender's
importer turns them to Z up), 40 degrees vertical field of view, 320 x 240, a grey-blue world
and one sun. TRANSPARENT_BOUNCES sets Cycles' `transparent_max_bounces`: each shell layer a ray
passes through is one bounce, so fur needs about twice its layer count (Blender's default is 8).
Prints one JSON line: {"objects": scene objects, "orphans": objects outside every scene}.
"""
import json
import math
import sys

import bpy
import mathutils

glb, png, bounces = sys.argv[1], sys.argv[2], int(sys.argv[3])
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=glb)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = 16
scene.cycles.seed = 1
scene.cycles.transparent_max_bounces = bounces
scene.render.resolution_x = 320
scene.render.resolution_y = 240
scene.render.threads_mode = "FIXED"
scene.render.threads = 2
world = bpy.data.worlds.new("world")
scene.world = world
world.use_nodes = True
background = world.node_tree.nodes["Background"]
background.inputs[0].default_value = (0.55, 0.6, 0.7, 1.0)
background.inputs[1].default_value = 1.0


def blender(v):
    """glTF (x, y, z), Y up, as Blender's importer places it (Z up)."""
    return mathutils.Vector((v[0], -v[2], v[1]))


camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
scene.collection.objects.link(camera)
camera.location = blender((1.2, 1.3, 2.4))
camera.rotation_euler = (blender((0.0, 0.6, 0.0)) - camera.location).to_track_quat("-Z", "Y").to_euler()
camera.data.lens_unit = "FOV"
camera.data.sensor_fit = "VERTICAL"
camera.data.angle = math.radians(40)
scene.camera = camera
sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
scene.collection.objects.link(sun)
sun.data.energy = 3.0
sun.rotation_euler = (0.6, 0.2, 0.5)
scene.render.filepath = png
bpy.ops.render.render(write_still=True)
orphans = [o for o in bpy.data.objects if not o.users_scene]
print(json.dumps({"objects": len(scene.objects), "orphans": len(orphans)}))
