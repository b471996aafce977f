//! The sRGB transfer function (IEC 61966-2-1) between 8-bit levels and linear light, and
//! CIELAB of linear sRGB colours.

/// An 8-bit sRGB level as linear light in [0, 1] (from a table of the 256 levels, made once:
/// the bake decodes every texel of masks and textures, a `powf` each).
pub fn decode8(v: u8) -> f64 {
    static TABLE: std::sync::OnceLock<[f64; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|v| decode(v as u8)))[v as usize]
}

fn decode(v: u8) -> f64 {
    unit(v as f64 / 255.0)
}

/// A 16-bit level of an sRGB-encoded value ([`crate::model::mesh::Rgba16`]) as linear light in [0, 1].
pub fn decode_unit(v: u16) -> f64 {
    unit(v as f64 / 65535.0)
}

fn unit(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light in [0, 1] as the nearest 8-bit sRGB level.
pub fn encode8(l: f64) -> u8 {
    let s = if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round().clamp(0.0, 255.0) as u8
}

/// CIELAB (D65 white) of a linear sRGB colour, each component clamped to [0, 1].
pub fn lab(c: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = c.map(|v| v.clamp(0.0, 1.0));
    let x = (0.4124 * r + 0.3576 * g + 0.1805 * b) / 0.950_47;
    let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let z = (0.0193 * r + 0.1192 * g + 0.9505 * b) / 1.088_83;
    let f = |t: f64| {
        if t > 216.0 / 24389.0 {
            t.cbrt()
        } else {
            (24389.0 / 27.0 * t + 16.0) / 116.0
        }
    };
    let (fx, fy, fz) = (f(x), f(y), f(z));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_table_is_the_formula() {
        for v in 0..=255u8 {
            assert_eq!(super::decode8(v).to_bits(), super::decode(v).to_bits());
        }
    }

    #[test]
    fn every_level_round_trips() {
        for v in 0..=255u8 {
            assert_eq!(super::encode8(super::decode8(v)), v);
        }
    }
}
