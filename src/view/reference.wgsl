// The runtime reference: the classic shell technique, one instance per layer.
// Vertex: extrude `position + delta * t_j` (+ `bend * t_j^k` under the gravity effect, + the
// wind's `sway * t_j^k' * sin(angle + phase)` at a time), then skin a skinned input. Fragment: sample the law texture
// (filtered, mipmapped, like the baked mask), test the strand law on the interpolated value and
// discard; shade by the layer colour times the occlusion's lerp(1 - a, 1, t), with the layer's
// sheen.

struct Shell {
    model: mat4x4<f32>,
    // mask tiles per UV unit (xy), mask size in texels (z), law: 0 noise, 1 cells (w)
    tiles: vec4<f32>,
    // noise: threshold
    law: vec4<f32>,
    // seed (as bits), layers shown, 1 when skinned, unused
    ints: vec4<u32>,
    // metallic, roughness, bend exponent k
    material: vec4<f32>,
    // per layer: linear rgb shade, t
    layers: array<vec4<f32>, 256>,
    // cells law: per-layer code cutoff, four to a vector
    cutoffs: array<vec4<f32>, 64>,
    // wind: angle 2π·time/period, growth exponent, 1 when swaying
    wind: vec4<f32>,
    // per layer: sheen colour (rgb) and roughness (w)
    sheen: array<vec4<f32>, 256>,
}

@group(1) @binding(0) var<uniform> shell: Shell;
// grey = strand shade (sRGB, decoded by the format), alpha = raw noise or survival code
@group(1) @binding(1) var law_texture: texture_2d<f32>;
@group(1) @binding(2) var law_sampler: sampler;
// a skinned input's joint matrices at the time (relative to the mesh origin)
@group(1) @binding(3) var<storage, read> joint_matrices: array<mat4x4<f32>>;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) delta: vec3<f32>,
    // density (1: none), the occlusion effect's darkening a, the wind effect's phase
    @location(4) scalars: vec3<f32>,
    // the gravity effect's bend at the tip, weighted t^k (k = shell.material.z)
    @location(5) bend: vec3<f32>,
    // the wind effect's sway at the tip
    @location(6) sway: vec3<f32>,
    // a skinned input's joints and weights
    @location(7) joints: vec4<f32>,
    @location(8) weights: vec4<f32>,
    // the asset's base colour at the strand root (white: none)
    @location(9) albedo: vec3<f32>,
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) layer: u32,
    @location(4) density: f32,
    @location(5) occlusion: f32,
    @location(6) albedo: vec3<f32>,
}

@vertex
fn vs_main(in: VsIn, @builtin(instance_index) layer: u32) -> VsOut {
    let t = shell.layers[layer].w;
    var p = in.position + in.delta * t + in.bend * pow(t, shell.material.z);
    if (shell.wind.z > 0.0) {
        p += in.sway * (pow(t, shell.wind.y) * sin(shell.wind.x + in.scalars.z));
    }
    var n = in.normal;
    if (shell.ints.z == 1u) {
        // skinned after the extrusion, as glTF applies morph targets before the skin
        let j = vec4<u32>(in.joints);
        let skin = joint_matrices[j.x] * in.weights.x + joint_matrices[j.y] * in.weights.y
            + joint_matrices[j.z] * in.weights.z + joint_matrices[j.w] * in.weights.w;
        p = (skin * vec4<f32>(p, 1.0)).xyz;
        n = (skin * vec4<f32>(n, 0.0)).xyz;
    }
    var out: VsOut;
    let world = shell.model * vec4<f32>(p, 1.0);
    out.world = world.xyz;
    out.clip = frame.view_proj * world;
    out.normal = n;
    // the tiling applied per vertex, as a file with the tiling in its coordinates holds it
    out.uv = in.uv * shell.tiles.xy;
    out.layer = layer;
    out.density = in.scalars.x;
    out.occlusion = in.scalars.y;
    out.albedo = in.albedo;
    return out;
}

// Whether the strand law holds for the sampled law value `a` on layer `j` at height `t`.
fn survives(a: f32, j: u32, t: f32) -> bool {
    if (shell.tiles.w == 0.0) {
        // Noise law, the seed's form: n·(1−t) >= c.
        return a * (1.0 - t) >= shell.law.x;
    }
    // Cells law: the survival code against the layer's cutoff.
    return a >= shell.cutoffs[j / 4u][j % 4u];
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let layer = shell.layers[in.layer];
    // Implicit derivatives pick the mip level (uniform control flow: before any discard).
    let law = textureSample(law_texture, law_sampler, in.uv);
    // The base layer (t = 0) is the opaque skin and never discards.
    // The density map scales the law's value (the baked file: COLOR_0 alpha times the mask's).
    if (in.layer > 0u && !survives(law.a * in.density, in.layer, layer.w)) {
        discard;
    }
    let occlusion = 1.0 - in.occlusion + in.occlusion * layer.w;
    let rgb = shade_sheen(layer.rgb * occlusion * in.albedo * law.rgb, shell.material.x, shell.material.y, shell.sheen[in.layer], normalize(in.normal), in.world);
    return vec4<f32>(rgb, 1.0);
}
