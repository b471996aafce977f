"""Builds the look test assets: small glTF files on which baked fur must keep the asset's look.

Usage: python3 tests/look_assets.py OUT_DIR
Needs Blender as a Python module (`import bpy`, Blender 5.0) and numpy. Each asset is built
from Blender's empty factory settings, its textures drawn here with numpy and packed into the
GLB, and exported with Blender's glTF exporter (Y up, materials, no animation). The furred
parts' materials are named `fur_*`, so a bake can pick them with `--only 'material=fur_*'`.

  striped_cat.glb    an animal about 1 unit long (body, head, tail) in one material `fur_coat`
                     whose texture is orange and black stripes, about ten across the body: the
                     fur must carry texture detail finer than the mesh. Its eyes are separate
                     small spheres (material `eye`) half sunk into the head, which the fur
                     must not bury; it stands on a plain `ground` plane.
  logo_crate.glb     a flat-shaded 1 x 0.6 x 0.6 box of 12 triangles whose texture (`fur_crate`)
                     is flat blue with a white roundel and arrow and a red stripe on the front
                     face: a decal far finer than the triangles, over hard edges.
  checker_panel.glb  a 1 x 1 panel of 8 x 8 quads, each with its own vertices, coloured by
                     vertex colours (COLOR_0) in a checker of red, green, blue and white under a
                     white base colour (`fur_panel`): colour that lives in the vertices only.
  degenerate_uv.glb  a UV sphere (`fur_ball`, plain light brown) whose UVs are the default but
                     for six triangles in one place collapsed to nearly a point: tiny nonzero UV
                     area over normal world area, as in real assets, which must not upset the
                     fur's UV-to-world scale.
  parts_robot.glb    a standing figure of rigid parts of very different sizes (torso, head, thin
                     arms, legs, small hands), each its own node under an empty `robot`, all in
                     `fur_robot` (plain yellow): fur that suits each part's size.
  no_material.glb    a torus whose primitive has no material at all.

Prints one JSON line: a list of {"name", "file", "eye", "target", "close_eye", "close_target"},
the cameras (glTF coordinates, Y up) to render each from: the far view frames the asset (for
the cat, the animal without its ground) for a 40 degree vertical field of view, and the close
view, at a fifth of that distance, looks at the patterned region.
"""
import contextlib
import json
import math
import os
import sys

import bpy
import mathutils
import numpy as np

FOV = math.radians(40.0)


# ---------------------------------------------------------------------------------------------
# Helpers


def gltf(v):
    """Blender (x, y, z), Z up, as the exporter writes it (glTF, Y up)."""
    return mathutils.Vector((v[0], v[2], -v[1]))


def fresh():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def mesh_object(name, op, location=(0.0, 0.0, 0.0), matrix=None, smooth=True, sharp_angle=None, **kw):
    """Adds a primitive with `op`, bakes `matrix` into its mesh, names object and mesh `name`
    and puts the object at `location` (so the node carries the translation)."""
    op(location=(0.0, 0.0, 0.0), **kw)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.name = name
    if matrix is not None:
        obj.data.transform(matrix)
    if smooth:
        obj.data.shade_smooth()
        if sharp_angle is not None:
            obj.data.set_sharp_from_angle(angle=sharp_angle)
    else:
        obj.data.shade_flat()
    obj.location = location
    return obj


def from_pydata(name, verts, faces, uvs=None, location=(0.0, 0.0, 0.0)):
    """A mesh object from vertices, faces and, if given, one UV per face corner."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    if uvs is not None:
        layer = mesh.uv_layers.new(name="UVMap")
        layer.data.foreach_set("uv", np.asarray(uvs, dtype=np.float32).ravel())
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    return obj


def uv_sphere(name, segments, rings, radius, location=(0.0, 0.0, 0.0), matrix=None):
    """A smooth UV sphere laid out as Blender's primitive is (poles on Z; u around Z from the seam
    at -X, 0.5 at +X; v from the bottom pole, 0, to the top, 1; triangle fans at the poles),
    built here because the primitive's face order changes from run to run."""
    verts = [(0.0, 0.0, radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = math.pi + 2 * math.pi * j / segments
            verts.append((radius * math.sin(theta) * math.cos(phi), radius * math.sin(theta) * math.sin(phi),
                          radius * math.cos(theta)))
    verts.append((0.0, 0.0, -radius))
    bottom = len(verts) - 1

    def ring(i, j):  # the vertex of ring i (1 .. rings - 1) and segment j
        return 1 + (i - 1) * segments + j % segments

    faces, uvs = [], []
    for j in range(segments):
        u0, u1, um = j / segments, (j + 1) / segments, (j + 0.5) / segments
        faces.append([0, ring(1, j), ring(1, j + 1)])
        uvs += [(um, 1.0), (u0, 1 - 1 / rings), (u1, 1 - 1 / rings)]
        for i in range(1, rings - 1):
            v0, v1 = 1 - i / rings, 1 - (i + 1) / rings
            faces.append([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1)])
            uvs += [(u0, v0), (u0, v1), (u1, v1), (u1, v0)]
        faces.append([ring(rings - 1, j), bottom, ring(rings - 1, j + 1)])
        uvs += [(u0, 1 / rings), (um, 0.0), (u1, 1 / rings)]
    obj = from_pydata(name, verts, faces, uvs, location=location)
    if matrix is not None:
        obj.data.transform(matrix)
    obj.data.shade_smooth()
    return obj


def image(name, rgb):
    """A packed image from an (H, W, 3) array in [0, 1], row 0 at the bottom (v = 0)."""
    h, w, _ = rgb.shape
    img = bpy.data.images.new(name, w, h, alpha=False)
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[:, :, :3] = np.clip(rgb, 0.0, 1.0)
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    return img


def material(name, color=(0.8, 0.8, 0.8), roughness=0.6, texture=None, vertex_color=None, double_sided=False):
    """A Principled material: a plain base colour, or an image texture, or a colour attribute
    (which the exporter writes as COLOR_0, with the base colour factor white). Closed solids
    are one-sided; `double_sided` for sheets."""
    mat = bpy.data.materials.new(name)
    mat.use_backface_culling = not double_sided
    tree = mat.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = 0.0
    if texture is not None:
        node = tree.nodes.new("ShaderNodeTexImage")
        node.image = texture
        node.interpolation = "Linear"
        tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    if vertex_color is not None:
        node = tree.nodes.new("ShaderNodeVertexColor")
        node.layer_name = vertex_color
        tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def assign(obj, mat):
    obj.data.materials.clear()
    obj.data.materials.append(mat)


def bounds(objects):
    """Corners (glTF coordinates) of the world box around the objects' vertices."""
    bpy.context.view_layer.update()
    pts = []
    for obj in objects:
        m = obj.matrix_world
        pts.extend(gltf(m @ v.co) for v in obj.data.vertices)
    lo = mathutils.Vector([min(p[i] for p in pts) for i in range(3)])
    hi = mathutils.Vector([max(p[i] for p in pts) for i in range(3)])
    return lo, hi


def cameras(objects, far_dir, close_target, close_dir):
    """The far view frames the objects' bounding sphere for FOV; the close view looks at
    `close_target` (glTF) from a fifth of the far distance. Directions are glTF, eye - target."""
    lo, hi = bounds(objects)
    target = (lo + hi) / 2
    radius = (hi - lo).length / 2
    dist = radius / math.sin(FOV / 2)
    eye = target + mathutils.Vector(far_dir).normalized() * dist
    close_target = mathutils.Vector(close_target)
    close_eye = close_target + mathutils.Vector(close_dir).normalized() * (dist / 5)
    r = lambda v: [round(c, 4) + 0.0 for c in v]
    return {"eye": r(eye), "target": r(target), "close_eye": r(close_eye), "close_target": r(close_target)}


def export(path):
    # The exporter logs to stdout; keep stdout for the JSON line.
    with contextlib.redirect_stdout(sys.stderr):
        _export(path)


def _export(path):
    bpy.ops.export_scene.gltf(
        filepath=path,
        check_existing=False,
        export_format="GLB",
        export_yup=True,
        export_apply=True,
        export_materials="EXPORT",
        export_image_format="AUTO",
        export_texcoords=True,
        export_normals=True,
        export_tangents=False,
        export_vertex_color="MATERIAL",
        export_all_vertex_colors=False,
        export_attributes=False,
        export_animations=False,
        export_morph=False,
        export_skins=False,
        export_cameras=False,
        export_lights=False,
        export_extras=False,
        use_mesh_edges=False,
        use_mesh_vertices=False,
    )


# ---------------------------------------------------------------------------------------------
# Textures


def stripes_texture(size=512, periods=10):
    """Orange with black stripes across v (the sphere's pole-to-pole axis), gently wavy along u
    (whole waves, so the texture wraps around u without a seam); 4 x 4 supersampled edges."""
    ss = 4
    n = size * ss
    u = (np.arange(n) + 0.5) / n
    v = (np.arange(n) + 0.5) / n
    uu, vv = np.meshgrid(u, v)
    k = np.floor(vv * periods)
    wave = 0.18 * np.sin(2 * math.pi * (2 * uu + 0.37 * k)) + 0.08 * np.sin(2 * math.pi * (5 * uu + 0.11 * k))
    phase = (vv * periods + wave / 2) % 1.0
    black = (phase < 0.42).astype(np.float32)
    black = black.reshape(size, ss, size, ss).mean(axis=(1, 3))[..., None]
    orange = np.array([0.95, 0.45, 0.05], dtype=np.float32)
    dark = np.array([0.03, 0.02, 0.01], dtype=np.float32)
    return orange * (1 - black) + dark * black


def crate_texture(size, front_box):
    """Flat blue; on the front face's island `front_box` (u0, v0, u1, v1) a white roundel (a
    ring with a bar through it ending in an arrowhead to the right) and a red stripe along the
    bottom; 4 x 4 supersampled."""
    ss = 4
    n = size * ss
    c = (np.arange(n) + 0.5) / n
    uu, vv = np.meshgrid(c, c)
    u0, v0, u1, v1 = front_box
    # Face coordinates in world units: x across (0..1), z up (0..0.6).
    fx = (uu - u0) / (u1 - u0) * 1.0
    fz = (vv - v0) / (v1 - v0) * 0.6
    on = (fx >= 0) & (fx <= 1.0) & (fz >= 0) & (fz <= 0.6)
    cx, cz = 0.40, 0.33
    r = np.hypot(fx - cx, fz - cz)
    ring = (r > 0.15) & (r < 0.225)
    bar = (np.abs(fz - cz) < 0.04) & (fx > cx - 0.32) & (fx < 0.70)
    # An arrowhead to the right, so the decal shows which way up and round it is.
    arrow = (fx >= 0.68) & (fx < 0.92) & (np.abs(fz - cz) < 0.12 * (0.92 - fx) / 0.24)
    white = on & (ring | bar | arrow)
    red = on & (fz > 0.035) & (fz < 0.085) & (fx > 0.04) & (fx < 0.96)
    blue = np.array([0.10, 0.28, 0.72], dtype=np.float32)
    out = np.empty((n, n, 3), dtype=np.float32)
    out[:] = blue
    out[red] = (0.85, 0.08, 0.06)
    out[white] = (1.0, 1.0, 1.0)
    return out.reshape(size, ss, size, ss, 3).mean(axis=(1, 3))


# ---------------------------------------------------------------------------------------------
# Assets


# The striped cat's body half-axes (x along the body) and how far it floats above the ground, its
# head (centre, radius) and its tail (where it leaves the body, its length, its lean back from
# the vertical), in Blender coordinates.
CAT_BODY = (0.32, 0.15, 0.16)
CAT_LIFT = 0.004
CAT_HEAD = ((0.36, 0.0, 0.40), 0.17)
CAT_TAIL = ((-0.27, 0.0, 0.22), 0.44, math.radians(40))


def cat_tail_ends():
    """Where the cat's tail starts and ends (Blender coordinates), and its rotation."""
    base, length, tilt = CAT_TAIL
    rot = mathutils.Matrix.Rotation(-tilt, 4, "Y")
    base = mathutils.Vector(base)
    return base, base + rot @ mathutils.Vector((0.0, 0.0, length)), rot


def cat_parts(coat, eye_mat, body_segments=(32, 16), lift=CAT_LIFT, open_tail=False):
    """The striped cat's body, head and tail (in `coat`) and its two eyes (in `eye_mat`).

    `open_tail`: a tail with an open end, subdivided once, for a character whose parts are
    joined into one mesh (`skinned_cat.py`); else a capped tail, sharp where its faces meet at
    over 40 degrees."""
    # Body: a sphere with its poles along X (so the stripes across v ring the body), stretched.
    a, b, c = CAT_BODY
    body_matrix = mathutils.Matrix.Diagonal((a, b, c, 1.0)) @ mathutils.Matrix.Rotation(math.pi / 2, 4, "Y")
    body = uv_sphere("body", *body_segments, 1.0, location=(0.0, 0.0, c + lift), matrix=body_matrix)
    head_c, head_r = mathutils.Vector(CAT_HEAD[0]), CAT_HEAD[1]
    head = uv_sphere("head", 32, 16, head_r, location=head_c)
    # Tail: a tapered tube from the body's rear, up and back.
    tail_base, tail_tip, tail_rot = cat_tail_ends()
    tail_centre = (tail_base + tail_tip) / 2
    cone = dict(vertices=16, radius1=0.045, radius2=0.022, depth=CAT_TAIL[1])
    if open_tail:
        tail = mesh_object("tail", bpy.ops.mesh.primitive_cone_add, location=tail_centre, matrix=tail_rot,
                           end_fill_type="NOTHING", **cone)
        bpy.ops.object.mode_set(mode="OBJECT")
        tail.modifiers.new("cuts", "SUBSURF").levels = 1
    else:
        tail = mesh_object("tail", bpy.ops.mesh.primitive_cone_add, location=tail_centre, matrix=tail_rot,
                           sharp_angle=math.radians(40), **cone)
    for obj in (body, head, tail):
        assign(obj, coat)

    # Eyes: centres on the head's surface, so half of each eyeball sticks out.
    eyes = []
    for name, side in (("eye_l", 1.0), ("eye_r", -1.0)):
        d = mathutils.Vector((0.80, 0.42 * side, 0.30)).normalized()
        eye = uv_sphere(name, 16, 8, 0.04, location=head_c + d * head_r)
        assign(eye, eye_mat)
        eyes.append(eye)
    return [body, head, tail], eyes


def striped_cat(path):
    fresh()
    coat = material("fur_coat", roughness=0.7, texture=image("cat_stripes", stripes_texture()))
    eye_mat = material("eye", color=(0.01, 0.01, 0.01), roughness=0.08)
    ground_mat = material("ground", color=(0.33, 0.40, 0.32), roughness=0.9, double_sided=True)
    parts, eyes = cat_parts(coat, eye_mat)

    ground = mesh_object("ground", bpy.ops.mesh.primitive_plane_add, smooth=False, size=2.0)
    assign(ground, ground_mat)

    export(path)
    # Close view: the stripes on the body's right flank (Blender -Y is glTF +Z).
    _, b, c = CAT_BODY
    flank = gltf((0.0, -b, c + CAT_LIFT))
    return cameras(parts + eyes, (1.2, 0.8, 2.2), flank, (0.3, 0.45, 1.0))


def logo_crate(path):
    fresh()
    sx, sy, sz = 0.5, 0.3, 0.3  # half sizes: 1 x 0.6 x 0.6, resting on the ground
    # Each face its own island at one texel density (k UV per world unit): a column of front,
    # back, top (1 x 0.6 each) and a column of the two ends (0.6 x 0.6) and the bottom (turned).
    k, m = 0.41, 0.02
    w, h = 1.0 * k, 0.6 * k

    def rect(u0, v0, du, dv):
        return (u0, v0, u0 + du, v0 + dv)

    islands = {
        "front": rect(m, 1 - m - h, w, h),
        "back": rect(m, 1 - 2 * m - 2 * h, w, h),
        "top": rect(m, 1 - 3 * m - 3 * h, w, h),
        "left": rect(2 * m + w, 1 - m - h, h, h),
        "right": rect(2 * m + w, 1 - 2 * m - 2 * h, h, h),
        "bottom": rect(2 * m + w, 1 - 3 * m - 2 * h - w, h, w),
    }
    X, Y, Z = sx, sy, 2 * sz
    # Faces as (island, corners in the order (u0,v0) (u1,v0) (u1,v1) (u0,v1)) with outward
    # normals: the front faces -Y (glTF +Z), seen upright with +X to the right.
    faces = [
        ("front", [(-X, -Y, 0), (X, -Y, 0), (X, -Y, Z), (-X, -Y, Z)]),
        ("back", [(X, Y, 0), (-X, Y, 0), (-X, Y, Z), (X, Y, Z)]),
        ("top", [(-X, -Y, Z), (X, -Y, Z), (X, Y, Z), (-X, Y, Z)]),
        ("right", [(X, -Y, 0), (X, Y, 0), (X, Y, Z), (X, -Y, Z)]),
        ("left", [(-X, Y, 0), (-X, -Y, 0), (-X, -Y, Z), (-X, Y, Z)]),
        ("bottom", [(-X, Y, 0), (X, Y, 0), (X, -Y, 0), (-X, -Y, 0)]),
    ]
    verts, polys, uvs = [], [], []
    for island, corners in faces:
        u0, v0, u1, v1 = islands[island]
        if island == "bottom":  # turned a quarter: its long side runs along v
            corner_uvs = [(u1, v0), (u1, v1), (u0, v1), (u0, v0)]
        else:
            corner_uvs = [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]
        # Shared corners are welded; flat shading splits the normals at export.
        idx = []
        for p in corners:
            if p not in verts:
                verts.append(p)
            idx.append(verts.index(p))
        polys.append(idx)
        uvs.extend(corner_uvs)
    crate = from_pydata("crate", verts, polys, uvs)
    crate.data.shade_flat()
    tex = image("crate_decal", crate_texture(512, islands["front"]))
    assign(crate, material("fur_crate", roughness=0.55, texture=tex))
    export(path)
    front = gltf((0.0, -Y, 0.33))
    return cameras([crate], (1.0, 0.8, 2.2), front, (0.25, 0.2, 1.0))


def checker_panel(path):
    fresh()
    n = 8
    size = 1.0
    bottom = 0.1
    palette = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    white = (1.0, 1.0, 1.0)
    verts, polys, colors = [], [], []
    # Upright in Blender's XZ plane facing -Y (glTF +Z), x -0.5..0.5, height `bottom`..+1.
    for j in range(n):
        for i in range(n):
            x0 = -size / 2 + i * size / n
            z0 = bottom + j * size / n
            d = size / n
            base = len(verts)
            verts += [(x0, 0.0, z0), (x0 + d, 0.0, z0), (x0 + d, 0.0, z0 + d), (x0, 0.0, z0 + d)]
            polys.append([base, base + 1, base + 2, base + 3])
            col = white if (i + j) % 2 == 0 else palette[(i // 2 + j) % 3]
            colors += [col] * 4
    panel = from_pydata("panel", verts, polys)
    attr = panel.data.color_attributes.new("Color", "FLOAT_COLOR", "POINT")
    rgba = np.ones((len(colors), 4), dtype=np.float32)
    rgba[:, :3] = colors
    attr.data.foreach_set("color", rgba.ravel())
    panel.data.color_attributes.active_color = attr
    panel.data.color_attributes.render_color_index = 0
    panel.data.shade_flat()
    # UVs: the panel's own square, so a texture-scale reading has something sane to read.
    uv = [((verts[vi][0] + size / 2) / size, (verts[vi][2] - bottom) / size) for p in polys for vi in p]
    layer = panel.data.uv_layers.new(name="UVMap")
    layer.data.foreach_set("uv", np.asarray(uv, dtype=np.float32).ravel())
    mat = material("fur_panel", color=(1.0, 1.0, 1.0), roughness=0.6, vertex_color="Color", double_sided=True)
    assign(panel, mat)
    export(path)
    centre = gltf((0.0, 0.0, bottom + size / 2))
    return cameras([panel], (0.6, 0.5, 2.4), centre, (0.15, 0.2, 1.0))


def degenerate_uv(path):
    fresh()
    r = 0.5
    ball = uv_sphere("ball", 48, 24, r, location=(0.0, 0.0, r))
    mesh = ball.data
    # Three neighbouring quads on the camera side, just above the equator.
    spot = mathutils.Vector((0.45, -0.85, 0.3)).normalized() * r
    quads = [p for p in mesh.polygons if p.loop_total == 4]
    nearest = min(quads, key=lambda p: (p.center - spot).length)
    ring_z = nearest.center.z
    row = sorted((p for p in quads if abs(p.center.z - ring_z) < 1e-6),
                 key=lambda p: (p.center - nearest.center).length)[:3]
    uv = mesh.uv_layers[0].data
    point = mathutils.Vector(uv[nearest.loop_start].uv)
    # Each corner within 1e-5 of the point, none the same, so every triangle keeps a tiny
    # nonzero UV area.
    offsets = [(0.0, 0.0), (6e-6, 1e-6), (7e-6, 6.5e-6), (1.5e-6, 5e-6)]
    for f, p in enumerate(sorted(row, key=lambda p: p.index)):
        for c, li in enumerate(p.loop_indices):
            du, dv = offsets[c]
            uv[li].uv = (point.x + du + 1e-6 * f, point.y + dv - 1e-6 * f)
    assign(ball, material("fur_ball", color=(0.45, 0.28, 0.14), roughness=0.7))
    export(path)
    patch = sum((p.center for p in row), mathutils.Vector()) / len(row)
    patch_world = ball.matrix_world @ patch
    normal = gltf(patch_world - ball.matrix_world.translation)
    return cameras([ball], (1.0, 0.7, 2.2), gltf(patch_world), normal + mathutils.Vector((0.0, 0.25, 0.0)))


def parts_robot(path):
    fresh()
    yellow = material("fur_robot", color=(0.95, 0.78, 0.10), roughness=0.5)
    robot = bpy.data.objects.new("robot", None)
    bpy.context.scene.collection.objects.link(robot)
    leg_len, leg_r = 0.7, 0.06
    torso_w, torso_h, torso_d = 0.6, 0.8, 0.4
    arm_len, arm_r = 0.6, 0.04
    head_r, hand_r = 0.18, 0.05
    hip = leg_len
    shoulder = hip + torso_h - 0.05
    caps = math.radians(40)  # cylinders: smooth sides, sharp rims
    parts = [
        mesh_object("torso", bpy.ops.mesh.primitive_cube_add, location=(0.0, 0.0, hip + torso_h / 2),
                    matrix=mathutils.Matrix.Diagonal((torso_w / 2, torso_d / 2, torso_h / 2, 1.0)),
                    smooth=False, size=2.0),
        uv_sphere("head", 32, 16, head_r, location=(0.0, 0.0, hip + torso_h + head_r - 0.02)),
    ]
    # The robot faces -Y (glTF +Z); its left is +X.
    for side, sx in (("l", 1.0), ("r", -1.0)):
        ax = sx * (torso_w / 2 + arm_r + 0.01)
        parts.append(mesh_object(f"arm_{side}", bpy.ops.mesh.primitive_cylinder_add,
                                 location=(ax, 0.0, shoulder - arm_len / 2), sharp_angle=caps,
                                 vertices=16, radius=arm_r, depth=arm_len))
        parts.append(uv_sphere(f"hand_{side}", 16, 8, hand_r,
                               location=(ax, 0.0, shoulder - arm_len - hand_r + 0.01)))
        parts.append(mesh_object(f"leg_{side}", bpy.ops.mesh.primitive_cylinder_add,
                                 location=(sx * 0.15, 0.0, leg_len / 2), sharp_angle=caps,
                                 vertices=16, radius=leg_r, depth=leg_len))
    for part in parts:
        assign(part, yellow)
        part.parent = robot
    export(path)
    # Close view: the left hand where it meets the arm, beside the torso.
    hand = gltf((torso_w / 2 + arm_r + 0.01, 0.0, shoulder - arm_len + 0.02))
    return cameras(parts, (0.8, 0.6, 2.2), hand, (0.5, 0.25, 1.0))


def no_material(path):
    fresh()
    major, minor = 0.5, 0.2
    torus = mesh_object("torus", bpy.ops.mesh.primitive_torus_add, location=(0.0, 0.0, major + minor),
                        matrix=mathutils.Matrix.Rotation(math.pi / 2, 4, "X"),
                        major_radius=major, minor_radius=minor, major_segments=48, minor_segments=16)
    torus.data.materials.clear()
    export(path)
    front = gltf((0.0, -minor, major + minor + major))  # the top of the ring, front of its tube
    return cameras([torus], (1.0, 0.7, 2.2), front, (0.2, 0.5, 1.0))


ASSETS = [
    ("striped_cat", striped_cat),
    ("logo_crate", logo_crate),
    ("checker_panel", checker_panel),
    ("degenerate_uv", degenerate_uv),
    ("parts_robot", parts_robot),
    ("no_material", no_material),
]


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: python3 tests/look_assets.py OUT_DIR")
    out_dir = sys.argv[1]
    os.makedirs(out_dir, exist_ok=True)
    listing = []
    for name, build in ASSETS:
        file = os.path.join(out_dir, name + ".glb")
        view = build(file)
        listing.append({"name": name, "file": file, **view})
    print(json.dumps(listing))


if __name__ == "__main__":
    main()
