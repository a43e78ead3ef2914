//! [`FurLook`]: the per-asset parameters of how fur is drawn that the shaders read from the `Fur`
//! uniform block — tint, shearing exponent, alpha threshold, the strand shading and the stacking
//! correction — with their defaults, and the block they fill ([`FurLook::fur_uniforms`]).

use furbake_formats::sections::shell_atlas::ShellAtlas;
pub use furbake_runtime::scene::FurShading;

use crate::layout::FurUniforms;

/// How one fur asset is drawn, as far as the `Fur` uniform block carries it. `furbake-render`'s
/// `RenderSettings` holds these among its pipeline choices; an engine fills its own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FurLook {
    /// Linear RGB multiplier of the vertex colours. Default `[1, 1, 1]`.
    pub tint: [f32; 3],
    /// Exponent k of the shell shearing, eq. 3.36. Default 2.
    pub shear_exponent: f32,
    /// Shell and fin fragments with alpha at or below this are discarded, in [0, 1). Default
    /// [`FurLook::BLEND_ALPHA_THRESHOLD`].
    pub alpha_threshold: f32,
    /// The strand shading's parameters (docs/design.md "Fur shading"). Default
    /// [`FurShading::default`].
    pub shading: FurShading,
    /// With blending, blend each layer with the asset's stacking exponent (`shell.wgsl`
    /// `stacked_alpha`, [`crate::stacking`]). Default true.
    pub stacking_correction: bool,
    /// The anisotropy clamp of the host's shell and fin atlas samplers (1 = isotropic; at most
    /// 16): the shell shader takes the mip level of its stacking exponents from the pixel
    /// footprint as that sampler does. Default 16, as `furbake-render` draws blended fur.
    pub anisotropy: f32,
}

impl FurLook {
    /// The alpha threshold with blending: 0, so only empty texels (alpha exactly 0, also after
    /// filtering) are skipped. The faint mip-averaged coverage of sparse hair tips is coverage the
    /// stacking exponents count on: skipping alpha up to 0.02 made a distant coat clearer than the
    /// hair volume, more so the more layers were drawn (docs/design.md "Rendering accuracy").
    pub const BLEND_ALPHA_THRESHOLD: f32 = 0.0;

    /// The `Fur` block for `shells` laid over the surface at `repeat_m` metres per atlas repeat
    /// (fins repeat their texture as often), drawing `drawn_layers` shell layers (at least 1 is
    /// written), with the scale vectors one per welded vertex (`scale_layout` 0; a renderer
    /// switches it to 1 when it uploads one per triangle corner).
    pub fn fur_uniforms(&self, shells: &ShellAtlas, repeat_m: f32, drawn_layers: u32) -> FurUniforms {
        let s = &self.shading;
        let ([r, g, b], [tr, tg, tb], [sr, sg, sb]) = (self.tint, s.tip_color, s.secondary_tint);
        FurUniforms {
            tint: [r, g, b, 1.0],
            fur_length_m: shells.fur_length_m,
            shear_exponent: self.shear_exponent,
            alpha_threshold: self.alpha_threshold,
            atlas_layers: shells.params.layers,
            drawn_layers: drawn_layers.max(1),
            fin_repeat_m: repeat_m,
            scale_layout: 0,
            pad1: 0,
            tip_color: [tr, tg, tb, s.root_occlusion],
            secondary_tint: [sr, sg, sb, s.secondary_noise],
            specular: [s.primary_strength, s.primary_exponent, s.secondary_strength, s.secondary_exponent],
            strand: [s.primary_shift, s.secondary_shift, s.back_light, s.kajiya_kay_diffuse],
            stacking: [if self.stacking_correction { 1.0 } else { 0.0 }, self.anisotropy.clamp(1.0, 16.0), 0.0, 0.0],
        }
    }
}

impl Default for FurLook {
    fn default() -> Self {
        FurLook {
            tint: [1.0, 1.0, 1.0],
            shear_exponent: 2.0,
            alpha_threshold: Self::BLEND_ALPHA_THRESHOLD,
            shading: FurShading::default(),
            stacking_correction: true,
            anisotropy: 16.0,
        }
    }
}
