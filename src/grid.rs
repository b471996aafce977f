//! The layer-height grid: the ground floor that the strand mask, the shells and the presets all
//! stand on, so none of them has to import another for it.
//!
//! Layer heights live on a grid of [`HEIGHT_STEPS`] steps, `t = k / HEIGHT_STEPS`; the 8-bit mask
//! stores survival codes `BASE_CODE + q` on the same grid, which is what makes one mask exact for
//! every layer (`strands.rs`). Two layers must not share a step, so a bake has at most
//! [`MAX_LAYERS`] layers.

/// Lowest alpha code of any texel; cells-law texels that survive only at the base hold it.
pub const BASE_CODE: u32 = 16;
/// Height steps of the layer grid: `t = k / HEIGHT_STEPS`, `k` in `0..=HEIGHT_STEPS`.
pub const HEIGHT_STEPS: u32 = 255 - BASE_CODE;
/// Highest number of layers a bake can have (base included): one per step.
pub const MAX_LAYERS: u32 = HEIGHT_STEPS;

/// Height step of layer `j` of `layers`: `round(j · HEIGHT_STEPS / layers)`.
pub fn layer_step(j: u32, layers: u32) -> u32 {
    assert!((1..=HEIGHT_STEPS).contains(&layers) && j < layers);
    ((j as u64 * HEIGHT_STEPS as u64 * 2 + layers as u64) / (2 * layers as u64)) as u32
}

/// Normalised height of step `k`, exactly as the reference shader receives it.
pub fn step_height(k: u32) -> f32 {
    k as f32 / HEIGHT_STEPS as f32
}

/// Cells law: the `alphaCutoff` that shows exactly the texels whose code reaches step `k`.
pub fn step_cutoff(k: u32) -> f32 {
    (BASE_CODE as f32 + k as f32 - 0.5) / 255.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_take_distinct_steps_from_the_base() {
        for layers in [1, 2, 16, 32, MAX_LAYERS] {
            let steps: Vec<u32> = (0..layers).map(|j| layer_step(j, layers)).collect();
            assert_eq!(steps[0], 0);
            assert!(steps.windows(2).all(|w| w[0] < w[1]), "{layers}");
            assert!(*steps.last().unwrap() < HEIGHT_STEPS);
        }
    }
}
