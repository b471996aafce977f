// glTF primitive: morph targets in the vertex shader, metallic-roughness shading, alpha test.
// The renderer substitutes the two marked lines per pipeline variant (morph target count,
// presence of COLOR_0, skinning), so a primitive binds exactly the streams it has. Morph targets
// apply before the skin, as glTF specifies.

struct Draw {
    model: mat4x4<f32>,
    normal_matrix: mat4x4<f32>,
    base_color: vec4<f32>,
    uv_row0: vec4<f32>,
    uv_row1: vec4<f32>,
    // morph target weights, four to a row
    weights: array<vec4<f32>, 2>,
    // metallic, roughness, alpha cutoff, alpha mode (0 OPAQUE, 1 MASK, 2 BLEND)
    material: vec4<f32>,
    // emissive rgb, w = 1 when the primitive has no NORMAL (flat shading)
    emissive: vec4<f32>,
    // KHR_materials_sheen colour (rgb) and roughness (w); zero: none
    sheen: vec4<f32>,
    // x: weight of the COLOR_0 morph target, y: a skinned draw's first joint matrix, z: 1 for
    // an unlit material (KHR_materials_unlit)
    color_weight: vec4<f32>,
}

@group(1) @binding(0) var<uniform> draw: Draw;
// joint world · inverse bind of every skinned draw, one after another
@group(3) @binding(0) var<storage, read> joint_matrices: array<mat4x4<f32>>;
@group(2) @binding(0) var base_texture: texture_2d<f32>;
@group(2) @binding(1) var base_sampler: sampler;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
//INPUTS
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) color: vec4<f32>,
}

@vertex
fn vs_main(in: VsIn) -> VsOut {
    var p = in.position;
    var nrm = in.normal;
//MORPH
//SKIN
    var out: VsOut;
    let world = draw.model * vec4<f32>(p, 1.0);
    out.world = world.xyz;
    out.clip = frame.view_proj * world;
    out.normal = (draw.normal_matrix * vec4<f32>(nrm, 0.0)).xyz;
    out.uv = in.uv;
//COLOR
    return out;
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    // Flat normal from screen derivatives, for primitives without NORMAL only (a uniform branch,
    // before any discard: derivatives need uniform control flow), oriented towards the eye.
    var flat_n = vec3<f32>(0.0);
    if (draw.emissive.w == 1.0) {
        flat_n = cross(dpdx(in.world), dpdy(in.world));
        if (dot(flat_n, frame.eye.xyz - in.world) < 0.0) {
            flat_n = -flat_n;
        }
    }
    let uv = vec2<f32>(dot(draw.uv_row0.xyz, vec3<f32>(in.uv, 1.0)), dot(draw.uv_row1.xyz, vec3<f32>(in.uv, 1.0)));
    // Implicit derivatives pick the mip level (uniform control flow: before any discard).
    let texel = textureSample(base_texture, base_sampler, uv);
    let base = draw.base_color * texel * in.color;
    // glTF 3.9.4: MASK renders the fragment iff alpha >= alphaCutoff.
    if (draw.material.w == 1.0 && base.a < draw.material.z) {
        discard;
    }
    if (draw.color_weight.z == 1.0) {
        return vec4<f32>(base.rgb, select(1.0, base.a, draw.material.w == 2.0));
    }
    var n = normalize(in.normal);
    if (!front) {
        n = -n;
    }
    if (draw.emissive.w == 1.0) {
        n = normalize(flat_n);
    }
    let rgb = shade_sheen(base.rgb, draw.material.x, draw.material.y, draw.sheen, n, in.world) + draw.emissive.xyz;
    return vec4<f32>(rgb, select(1.0, base.a, draw.material.w == 2.0));
}
