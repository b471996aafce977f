// Shared by the glTF renderer and the runtime reference: frame uniforms and the glTF
// metallic-roughness BRDF (glTF 2.0 spec, Appendix B) with Cook-Torrance specular:
// GGX distribution, Smith-Schlick geometry (Schlick-GGX, k = alpha / 2), Schlick Fresnel;
// KHR_materials_sheen layered on top (Charlie distribution, Neubelt visibility, albedo scaling
// 1 − max(sheen colour) · 0.157).

struct Frame {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    light_dir: vec4<f32>,
    light_color: vec4<f32>,
    ambient: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;

const PI: f32 = 3.14159265358979;

fn schlick_g1(n_dot_x: f32, k: f32) -> f32 {
    return n_dot_x / (n_dot_x * (1.0 - k) + k);
}

// Outgoing linear radiance at a surface point `p` (anchor-relative) with unit normal `n`.
fn shade(base: vec3<f32>, metallic: f32, roughness: f32, n: vec3<f32>, p: vec3<f32>) -> vec3<f32> {
    let v = normalize(frame.eye.xyz - p);
    let l = frame.light_dir.xyz;
    let h = normalize(l + v);
    let r = clamp(roughness, 0.03, 1.0);
    let alpha = r * r;
    let a2 = alpha * alpha;
    let n_dot_l = clamp(dot(n, l), 0.0, 1.0);
    let n_dot_v = clamp(abs(dot(n, v)), 1e-4, 1.0);
    let n_dot_h = clamp(dot(n, h), 0.0, 1.0);
    let v_dot_h = clamp(dot(v, h), 0.0, 1.0);

    let f0 = mix(vec3<f32>(0.04), base, metallic);
    let fresnel = f0 + (vec3<f32>(1.0) - f0) * pow(1.0 - v_dot_h, 5.0);
    let d_den = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    let distribution = a2 / (PI * d_den * d_den);
    let k = alpha * 0.5;
    let geometry = schlick_g1(n_dot_l, k) * schlick_g1(n_dot_v, k);
    let specular = fresnel * distribution * geometry / max(4.0 * n_dot_l * n_dot_v, 1e-4);
    let c_diff = mix(base, vec3<f32>(0.0), metallic);
    let diffuse = (vec3<f32>(1.0) - fresnel) * c_diff / PI;
    return (diffuse + specular) * frame.light_color.xyz * n_dot_l + frame.ambient.xyz * base;
}

// Charlie sheen distribution (Estevez and Kulla 2017), alpha = sheen roughness squared.
fn charlie_d(alpha: f32, n_dot_h: f32) -> f32 {
    let inv = 1.0 / max(alpha, 1e-3);
    let sin2 = max(1.0 - n_dot_h * n_dot_h, 0.0078125);
    return (2.0 + inv) * pow(sin2, inv * 0.5) / (2.0 * PI);
}

// `shade` with a KHR_materials_sheen layer: `sheen.rgb` colour, `sheen.w` roughness (a zero
// colour leaves `shade` unchanged).
fn shade_sheen(base: vec3<f32>, metallic: f32, roughness: f32, sheen: vec4<f32>, n: vec3<f32>, p: vec3<f32>) -> vec3<f32> {
    let under = shade(base, metallic, roughness, n, p);
    let strength = max(sheen.r, max(sheen.g, sheen.b));
    if (strength <= 0.0) {
        return under;
    }
    let v = normalize(frame.eye.xyz - p);
    let l = frame.light_dir.xyz;
    let h = normalize(l + v);
    let n_dot_l = clamp(dot(n, l), 0.0, 1.0);
    let n_dot_v = clamp(abs(dot(n, v)), 1e-4, 1.0);
    let n_dot_h = clamp(dot(n, h), 0.0, 1.0);
    let r = max(sheen.w, 0.07);
    let visibility = 1.0 / max(4.0 * (n_dot_l + n_dot_v - n_dot_l * n_dot_v), 1e-4);
    let f_sheen = sheen.rgb * charlie_d(r * r, n_dot_h) * visibility;
    return under * (1.0 - strength * 0.157) + f_sheen * frame.light_color.xyz * n_dot_l;
}
