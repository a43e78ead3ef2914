//! The shells' level of detail (docs/design.md "Shell level of detail"): how many shell layers
//! one view draws, from the fur's projected length in pixels. Fur far away draws fewer layers
//! (the fins stand in for the lost side view); the counts halve, so the layers of a level are
//! every other layer of the level above, and a change of level fades the in-between layers in
//! or out instead of popping.

use glam::{Mat4, Vec3, Vec4};

/// How the shell count follows the fur's projected length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellLod {
    /// Shell layers per pixel of projected fur length (the longest the fur appears in this view,
    /// at the nearest point of the pack's bounds). Default [`ShellLod::DEFAULT_LAYERS_PER_PX`].
    pub layers_per_px: f32,
    /// The fewest layers drawn, however far the fur is. Default [`ShellLod::DEFAULT_MIN_LAYERS`].
    pub min_layers: u32,
}

impl ShellLod {
    /// The default slope, from `make report`'s level-of-detail sweep (docs/rendering-accuracy.md
    /// "Level of detail: the knee"): the knee lies at about one layer per pixel of fur length
    /// (16 layers at 16 px, 32 at 32 px) ...
    pub const DEFAULT_LAYERS_PER_PX: f32 = 1.0;
    /// ... and never below 16 layers, however short the fur (at 0.25–16 px the knee is 16: 8
    /// layers of the `fur` preset's coat, 4 atlas texels apart along a 45° ray, let the ray
    /// through between them).
    pub const DEFAULT_MIN_LAYERS: u32 = 16;

    /// Checks the ranges: `layers_per_px` finite and > 0, `min_layers` ≥ 1.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.layers_per_px.is_finite() && self.layers_per_px > 0.0) {
            return Err(format!("lod.layers_per_px = {} must be finite and above 0", self.layers_per_px));
        }
        if self.min_layers == 0 {
            return Err("lod.min_layers must be at least 1".into());
        }
        Ok(())
    }

    /// What a view draws of fur that projects to `fur_px` pixels with at most `max_layers`: the
    /// shell layers, and the opacity in (0, 1] of the layers a transition between two levels is
    /// adding (1 outside a transition).
    pub fn layers(&self, max_layers: u32, fur_px: f32) -> (u32, f32) {
        let level = ShellLevel::of(max_layers, self, fur_px);
        (level.layers, level.fade)
    }
}

impl Default for ShellLod {
    fn default() -> Self {
        ShellLod { layers_per_px: Self::DEFAULT_LAYERS_PER_PX, min_layers: Self::DEFAULT_MIN_LAYERS }
    }
}

/// The shells one view draws.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellLevel {
    /// Instances of the shell draw; layer i sits at height (i + 1)/layers.
    pub layers: u32,
    /// Opacity of the layers a transition is adding (the even-indexed ones, which the level
    /// below does not have), in (0, 1]; 1 outside a transition.
    pub fade: f32,
    /// The continuous layer count between the two levels (what the stacking of one hair's
    /// coverage over the layers reads, `shell.wgsl` `stacked_alpha`).
    pub continuous: f32,
}

impl ShellLevel {
    /// All `layers`, no transition.
    pub fn full(layers: u32) -> ShellLevel {
        ShellLevel { layers, fade: 1.0, continuous: layers as f32 }
    }

    /// The level for fur that projects to `fur_px` pixels, drawing at most `max_layers`: the
    /// wanted count `fur_px × layers_per_px`, clamped to [`min_layers`, `max_layers`], lies
    /// between two halvings of `max_layers`, N and 2N; the level draws 2N layers with the N
    /// that 2N adds faded by how far the wanted count is above N. Only exact halvings are
    /// levels (an odd count has none below it).
    pub fn of(max_layers: u32, lod: &ShellLod, fur_px: f32) -> ShellLevel {
        if max_layers == 0 {
            return ShellLevel::full(0);
        }
        let floor = lod.min_layers.clamp(1, max_layers);
        let wanted = (fur_px.max(0.0) * lod.layers_per_px).clamp(floor as f32, max_layers as f32);
        // The largest level at or below `wanted`: halve while the half is still a level.
        let mut low = max_layers;
        while low.is_multiple_of(2) && low / 2 >= floor && (low as f32) > wanted {
            low /= 2;
        }
        if low as f32 >= wanted || low == max_layers {
            return ShellLevel::full(low);
        }
        let fade = ((wanted - low as f32) / low as f32).clamp(0.0, 1.0);
        if fade <= 1e-3 {
            return ShellLevel::full(low);
        }
        ShellLevel { layers: 2 * low, fade, continuous: wanted }
    }

    /// The `shells` vector of the `Frame` uniform block for this level.
    pub fn uniform(&self) -> [f32; 4] {
        [self.layers as f32, self.fade, self.continuous, 0.0]
    }
}

/// How long, in pixels of a `viewport` (width, height), fur of `fur_length_m` (in the pack's
/// frame) appears at the point of the bounding sphere (`center`, `radius`, pack frame) nearest
/// the `eye`, measured across the view direction there, for a pack placed by `model` (rotation,
/// translation, uniform scale) and seen through `view_proj` (world → clip); `None` when the
/// viewport is empty, the eye is inside the sphere or the point is behind the camera (draw
/// everything then).
pub fn projected_fur_px(
    view_proj: Mat4,
    eye: Vec3,
    viewport: [f32; 2],
    model: Mat4,
    center: Vec3,
    radius: f32,
    fur_length_m: f32,
) -> Option<f32> {
    let [width, height] = viewport;
    if !(width > 0.0 && height > 0.0) {
        return None;
    }
    let scale = model.x_axis.truncate().length();
    let (c, r, length) = (model.transform_point3(center), radius * scale, fur_length_m * scale);
    let to_eye = eye - c;
    let distance = to_eye.length();
    if distance.is_nan() || distance <= r {
        return None;
    }
    let dir = to_eye / distance;
    let near = c + dir * r;
    // Two directions across the view ray; the longer projection is the fur's length in pixels.
    let across = dir.any_orthonormal_pair();
    let pixel = |p: Vec3| -> Option<glam::Vec2> {
        let clip: Vec4 = view_proj * p.extend(1.0);
        (clip.w > 1e-9).then(|| glam::Vec2::new(clip.x / clip.w * 0.5 * width, clip.y / clip.w * 0.5 * height))
    };
    let at = pixel(near)?;
    let mut px = 0.0f32;
    for a in [across.0, across.1] {
        px = px.max((pixel(near + a * length)? - at).length());
    }
    px.is_finite().then_some(px)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_halve_and_fade_between() {
        let lod = ShellLod { layers_per_px: 2.0, min_layers: 4 };
        // Near: everything.
        assert_eq!(ShellLevel::of(16, &lod, 100.0), ShellLevel::full(16));
        assert_eq!(ShellLevel::of(16, &lod, 8.0), ShellLevel::full(16));
        // Wanted 8 exactly: level 8, no fade.
        assert_eq!(ShellLevel::of(16, &lod, 4.0), ShellLevel::full(8));
        // Wanted 12: 16 layers with the 8 added ones at half opacity.
        let l = ShellLevel::of(16, &lod, 6.0);
        assert_eq!((l.layers, l.continuous), (16, 12.0));
        assert!((l.fade - 0.5).abs() < 1e-6, "{l:?}");
        // Far: never below the floor.
        assert_eq!(ShellLevel::of(16, &lod, 0.1), ShellLevel::full(4));
        // The floor above the maximum: the maximum.
        assert_eq!(ShellLevel::of(2, &lod, 0.0), ShellLevel::full(2));
        // An odd maximum has no level below it.
        assert_eq!(ShellLevel::of(13, &lod, 0.0), ShellLevel::full(13));
        assert_eq!(ShellLevel::of(0, &lod, 5.0), ShellLevel::full(0));
    }

    #[test]
    fn the_continuous_count_is_continuous_across_levels() {
        // As the fur shrinks, the continuous count and the opacity the faded layers add never
        // jump: just below a level's count the level above draws with its added layers at fade
        // → 0, which is the level itself.
        let lod = ShellLod { layers_per_px: 1.0, min_layers: 2 };
        let mut last = ShellLevel::of(64, &lod, 64.0);
        let mut px = 64.0f32;
        while px > 1.0 {
            px *= 0.995;
            let l = ShellLevel::of(64, &lod, px);
            assert!((l.continuous - last.continuous).abs() < 0.5, "{last:?} → {l:?} at {px}");
            // Opacity contributed: the layers of the lower level (full) plus the added ones × fade.
            let weight = |l: &ShellLevel| {
                if l.fade < 1.0 { l.layers as f32 / 2.0 * (1.0 + l.fade) } else { l.layers as f32 }
            };
            assert!((weight(&l) - weight(&last)).abs() < 0.5, "{last:?} → {l:?} at {px}");
            last = l;
        }
        assert_eq!(last, ShellLevel::full(2));
    }
}
