// The runtime reference: the classic shell technique, one instance per layer.
// Vertex: extrude `position + delta * t_j`. Fragment: evaluate the strand law and discard.
// The integer hash and the cell law mirror `strands.rs` operation for operation (u32 wrapping
// arithmetic, the same f32 expression order).

struct Shell {
    model: mat4x4<f32>,
    // mask tiles per UV unit (xy), mask size in texels (z), law: 0 noise, 1 cells (w)
    tiles: vec4<f32>,
    // noise: threshold; cells: thickness, min_length, texels_per_cell (as f32)
    law: vec4<f32>,
    // seed (as bits), layers shown, unused, unused
    ints: vec4<u32>,
    // metallic, roughness
    material: vec4<f32>,
    // per layer: linear rgb shade, t
    layers: array<vec4<f32>, 256>,
}

@group(1) @binding(0) var<uniform> shell: Shell;
@group(1) @binding(1) var noise_texture: texture_2d<f32>;
@group(1) @binding(2) var noise_sampler: sampler;

struct VsIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) delta: vec3<f32>,
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) layer: u32,
}

@vertex
fn vs_main(in: VsIn, @builtin(instance_index) layer: u32) -> VsOut {
    let t = shell.layers[layer].w;
    let p = in.position + in.delta * t;
    var out: VsOut;
    let world = shell.model * vec4<f32>(p, 1.0);
    out.world = world.xyz;
    out.clip = frame.view_proj * world;
    out.normal = in.normal;
    out.uv = in.uv;
    out.layer = layer;
    return out;
}

fn mix32(x0: u32) -> u32 {
    var x = x0;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

fn cell_hash(cx: u32, cy: u32, cells: u32, seed: u32) -> u32 {
    return mix32((cy * cells + cx) ^ mix32(seed + 0x9e3779b9u));
}

fn cell_rand(cx: u32, cy: u32, cells: u32, seed: u32) -> f32 {
    return f32(cell_hash(cx, cy, cells, seed) >> 8u) / 16777216.0;
}

// Whether the strand law holds at mask coordinate `m` (in tiles) and height `t`.
fn survives(m: vec2<f32>, t: f32) -> bool {
    let size = u32(shell.tiles.z);
    if (shell.tiles.w == 0.0) {
        // Noise law: the raw noise texture, n·(1−t) >= c. The unorm sample is turned back into
        // its byte and divided by 255 as `strands::survives` does, so no driver's unorm
        // conversion can move a texel across the threshold.
        let raw = textureSampleLevel(noise_texture, noise_sampler, m, 0.0).r;
        let n = f32(u32(round(raw * 255.0))) / 255.0;
        return n * (1.0 - t) >= shell.law.x;
    }
    // Cells law: texel index from the fractional tile coordinate, then `strands::survival`.
    let f = fract(m) * f32(size);
    let x = min(u32(f.x), size - 1u);
    let y = min(u32(f.y), size - 1u);
    let tpc = u32(shell.law.z);
    let cells = size / tpc;
    let cx = x / tpc;
    let cy = y / tpc;
    let lx = (f32(x % tpc) + 0.5) / f32(tpc) - 0.5;
    let ly = (f32(y % tpc) + 0.5) / f32(tpc) - 0.5;
    let dist = sqrt(lx * lx + ly * ly);
    let r = cell_rand(cx, cy, cells, shell.ints.x);
    let len = shell.law.y + (1.0 - shell.law.y) * r;
    return len - dist / shell.law.x >= t;
}

@fragment
fn fs_main(in: VsOut) -> @location(0) vec4<f32> {
    let layer = shell.layers[in.layer];
    let m = in.uv * shell.tiles.xy;
    // The base layer (t = 0) is the opaque skin and never discards.
    if (in.layer > 0u && !survives(m, layer.w)) {
        discard;
    }
    let rgb = shade(layer.rgb, shell.material.x, shell.material.y, normalize(in.normal), in.world);
    return vec4<f32>(rgb, 1.0);
}
