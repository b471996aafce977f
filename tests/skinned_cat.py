"""Builds a skinned, animated character in Blender for `shellbake bench`: the striped cat of
`look_assets.py` (body, head and tail in `fur_coat`, a striped texture; eyes in `eye`), without
its ground, on an armature of six bones (hips, chest, head, three along the tail) weighted by
Blender's automatic weights, with one looping 2 s clip `wag` that swings the tail and nods the
head.

Usage: python3 tests/skinned_cat.py OUT.glb
Needs Blender as a Python module (`import bpy`, Blender 5.0) and numpy, as look_assets.py does.
"""
import contextlib
import os
import sys

import bpy
import mathutils

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import look_assets as la  # noqa: E402


def build():
    la.fresh()
    coat = la.material("fur_coat", roughness=0.7, texture=la.image("cat_stripes", la.stripes_texture()))
    eye_mat = la.material("eye", color=(0.01, 0.01, 0.01), roughness=0.08)
    body_parts, eyes = la.cat_parts(coat, eye_mat, body_segments=(48, 24), lift=0.0, open_tail=True)
    parts = body_parts + eyes
    body = body_parts[0]
    _, _, c = la.CAT_BODY
    head_c = mathutils.Vector(la.CAT_HEAD[0])
    tail_base, tip, _ = la.cat_tail_ends()

    # One mesh object (a character's parts as one skinned mesh of two materials).
    for obj in parts:
        obj.select_set(True)
    bpy.context.view_layer.objects.active = body
    bpy.ops.object.convert(target="MESH")
    bpy.ops.object.join()
    cat = bpy.context.active_object
    cat.name = "cat"
    cat.data.name = "cat"

    arm_data = bpy.data.armatures.new("rig")
    rig = bpy.data.objects.new("rig", arm_data)
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    chain = [
        ("hips", (-0.05, 0.0, c), (-0.25, 0.0, 0.2), None),
        ("chest", (-0.05, 0.0, c), (0.25, 0.0, c + 0.05), None),
        ("head", (0.25, 0.0, c + 0.05), tuple(head_c + mathutils.Vector((0.1, 0.0, 0.1))), "chest"),
        ("tail_0", tuple(tail_base), tuple(tail_base.lerp(tip, 1 / 3)), "hips"),
        ("tail_1", tuple(tail_base.lerp(tip, 1 / 3)), tuple(tail_base.lerp(tip, 2 / 3)), "tail_0"),
        ("tail_2", tuple(tail_base.lerp(tip, 2 / 3)), tuple(tip), "tail_1"),
    ]
    for name, h, t, parent in chain:
        bone = arm_data.edit_bones.new(name)
        bone.head, bone.tail = h, t
        if parent:
            bone.parent = arm_data.edit_bones[parent]
            bone.use_connect = parent != "chest"
    bpy.ops.object.mode_set(mode="OBJECT")

    bpy.ops.object.select_all(action="DESELECT")
    cat.select_set(True)
    rig.select_set(True)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.parent_set(type="ARMATURE_AUTO")

    scene = bpy.context.scene
    scene.render.fps = 24
    scene.frame_start, scene.frame_end = 1, 49
    rig.animation_data_create()
    rig.animation_data.action = bpy.data.actions.new("wag")
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="POSE")
    for frame, swing, nod in ((1, 0.0, 0.0), (13, 0.5, 0.15), (25, 0.0, 0.0), (37, -0.5, -0.15), (49, 0.0, 0.0)):
        for name in ("tail_0", "tail_1", "tail_2"):
            pb = rig.pose.bones[name]
            pb.rotation_mode = "XYZ"
            pb.rotation_euler = (swing, 0.0, 0.0)
            pb.keyframe_insert("rotation_euler", frame=frame)
        pb = rig.pose.bones["head"]
        pb.rotation_mode = "XYZ"
        pb.rotation_euler = (0.0, nod, 0.0)
        pb.keyframe_insert("rotation_euler", frame=frame)
    bpy.ops.object.mode_set(mode="OBJECT")


def export(path):
    with contextlib.redirect_stdout(sys.stderr):
        bpy.ops.export_scene.gltf(
            filepath=path, check_existing=False, export_format="GLB", export_yup=True,
            export_apply=False, export_materials="EXPORT", export_texcoords=True, export_normals=True,
            export_tangents=False, export_animations=True, export_skins=True, export_morph=False,
            export_cameras=False, export_lights=False, export_extras=False,
        )


if __name__ == "__main__":
    build()
    export(sys.argv[1])
