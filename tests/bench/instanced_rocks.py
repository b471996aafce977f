"""Writes an asset as a set dresser brings one: one rock mesh (an icosphere, 642 vertices, no UVs)
placed 100 times by Blender as linked duplicates, each turned and uniformly scaled at random
(seeded), exported with Blender's own glTF exporter. Baked with moss, every instance is a part of
its own: what a bake of many small parts costs, and how Blender writes their transforms (a
uniform scale can come out one f32 ulp uneven).

Usage: python3 tests/bench/instanced_rocks.py OUT.glb
       shellbake bake OUT.glb --preset moss
"""
import random
import sys

import bpy

out = sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
random.seed(3)
material = bpy.data.materials.new("moss_rock")
bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=0.5)
rock = bpy.context.object
rock.name = "rock_000"
rock.data.name = "rock"
rock.data.materials.append(material)
for i in range(1, 100):
    r = rock.copy()
    r.name = f"rock_{i:03d}"
    bpy.context.collection.objects.link(r)
    r.location = (random.uniform(-10, 10), random.uniform(-10, 10), 0)
    r.rotation_euler = (random.uniform(0, 3), random.uniform(0, 3), random.uniform(0, 3))
    s = random.uniform(0.5, 1.5)
    r.scale = (s, s, s)
bpy.ops.export_scene.gltf(filepath=out, export_format="GLB")
