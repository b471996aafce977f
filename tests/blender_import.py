"""Imports a glTF file with Blender's own importer (the `bpy` module) twice, with "Import Scene
as Collection" on (Blender's default) and off, and prints what a Blender user then has: one JSON
line per import,
{"as_collection": bool, "visible": objects drawn in the active view layer,
 "in_scene": objects of the active Blender scene, "orphan_nodes": whether an "Orphan Nodes"
 collection exists, "scenes": the Blender scenes}.

Usage: python3 tests/blender_import.py FILE.glb
"""
import json
import sys

import bpy

glb = sys.argv[1]
for as_collection in (True, False):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=glb, import_scene_as_collection=as_collection)
    scene, layer = bpy.context.scene, bpy.context.view_layer
    print(json.dumps({
        "as_collection": as_collection,
        "visible": sorted(o.name for o in layer.objects if o.visible_get()),
        "in_scene": sorted(o.name for o in scene.objects),
        "orphan_nodes": any(c.name.startswith("Orphan Nodes") for c in bpy.data.collections),
        "scenes": sorted(s.name for s in bpy.data.scenes),
    }))
