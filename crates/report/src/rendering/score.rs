//! The scores of a furbake frame against its reference: NVIDIA FLIP (Andersson et al. 2020,
//! through the `nv-flip` crate, at its default 67 pixels per degree) — the mean and the weighted
//! 99th percentile of the error map over the whole image, and the mean over the pixels where
//! either image draws the mesh — and the coverage IoU: pixels the frame draws (any colour other
//! than the cleared background) against pixels the reference covers (at least half of their
//! samples hit skin or hair).

use super::reference::{ReferenceImage, linear_to_srgb8};

/// The scores of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Score {
    /// FLIP mean over the image, in [0, 1].
    pub flip_mean: f32,
    /// FLIP weighted 99th percentile over the image.
    pub flip_p99: f32,
    /// FLIP mean over the pixels either image covers.
    pub flip_mean_covered: f32,
    /// |covered by both| / |covered by either|.
    pub iou: f32,
}

/// Scores `test` (sRGB RGBA8, as read back) against `reference` whose background was the linear
/// `background`; also returns the FLIP error map coloured with the magma LUT (RGB8).
pub fn score(reference: &ReferenceImage, test: &image::RgbaImage, background: [f32; 3]) -> (Score, Vec<u8>) {
    let (w, h) = (reference.width, reference.height);
    let ref_rgb = reference.to_srgb8();
    let test_rgb: Vec<u8> = test.pixels().flat_map(|p| [p[0], p[1], p[2]]).collect();
    let bg = background.map(linear_to_srgb8);
    let err = nv_flip::flip(
        nv_flip::FlipImageRgb8::with_data(w, h, &ref_rgb),
        nv_flip::FlipImageRgb8::with_data(w, h, &test_rgb),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    let mut pool = nv_flip::FlipPool::from_image(&err);
    let values = err.to_vec();
    let (mut both, mut either, mut covered_sum) = (0u32, 0u32, 0.0f64);
    for (i, px) in test_rgb.chunks_exact(3).enumerate() {
        let drawn = px.iter().zip(&bg).any(|(a, b)| a.abs_diff(*b) > 1);
        let truth = reference.coverage[i] >= 0.5;
        both += u32::from(drawn && truth);
        if drawn || truth {
            either += 1;
            covered_sum += values[i] as f64;
        }
    }
    let map = err.apply_color_lut(&nv_flip::magma_lut()).to_vec();
    let score = Score {
        flip_mean: pool.mean(),
        flip_p99: pool.get_percentile(0.99, true),
        flip_mean_covered: if either == 0 { 0.0 } else { (covered_sum / either as f64) as f32 },
        iou: if either == 0 { 1.0 } else { both as f32 / either as f32 },
    };
    (score, map)
}
