//! The fur's strand shading (docs/design.md "Fur shading"): [`FurShading`], its parameters (one
//! set per renderer, [`crate::RenderSettings::shading`], or per scene pack, `[packs.shading]`),
//! their packing into the fur uniforms (`furbake_draw::FurLook`), and the CPU twin of the hair direction the shaders shade
//! along ([`strand_tangent`], `strand_tangent` in `shaders/fur_common.wgsl`).

#[cfg(feature = "testing")]
use glam::Vec3;

/// The strand shading's parameters, defaults and ranges (defined with the runtime's scene
/// description, which reads them from `[packs.shading]`; see its documentation for each field).
pub use furbake_runtime::scene::FurShading;

use crate::RenderError;

/// Checks `shading`'s ranges ([`FurShading::validate`]) as a [`RenderError::Shading`] naming the
/// field.
pub(crate) fn check(shading: &FurShading) -> Result<(), RenderError> {
    shading.validate().map_err(|(field, what)| RenderError::Shading { field, what })
}

#[cfg(feature = "testing")]
/// The unit hair direction the shaders shade along at relative height `t` in [0, 1] above a
/// vertex with unit normal `normal` and scale vector `scale_vector` (eq. 3.35): the derivative of
/// the eq. 3.36 shell offset `n·t + t^k·(s − n)` along `t`, `n + k·t^(k−1)·(s − n)`, normalised
/// — `normal` itself at rest (`s = n`) or without shearing (`shear` false, the `SHEAR` switch).
/// Where the offset points into the surface (an inward scale vector, which the shader lays flat,
/// fur thesis §3.4.3) the direction's inward part is dropped too. The CPU twin of
/// `strand_tangent` in `shaders/fur_common.wgsl`, in the same order of operations (f32); tests
/// compare it with the GPU's ([`crate::FurRenderer::shell_tangents`]).
pub fn strand_tangent(normal: [f32; 3], scale_vector: [f32; 3], t: f32, shear_exponent: f32, shear: bool) -> [f32; 3] {
    let (n, s, k) = (Vec3::from(normal), Vec3::from(scale_vector), shear_exponent);
    if !shear {
        return normal;
    }
    let mut d = n + k * t.max(1e-4).powf(k - 1.0) * (s - n);
    if (n * t + t.powf(k) * (s - n)).dot(n) < 0.0 {
        d -= d.dot(n) * n;
    }
    let len2 = d.dot(d);
    if len2.is_nan() || len2 <= 1e-12 {
        return normal;
    }
    (d / len2.sqrt()).to_array()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tangent_is_the_normal_at_rest_and_tilts_with_the_scale_vector() {
        let n = Vec3::new(0.3, 0.9, -0.2).normalize();
        for t in [0.0, 0.0625, 0.5, 1.0] {
            for k in [1.0, 2.0, 3.0] {
                let rest = Vec3::from(strand_tangent(n.to_array(), n.to_array(), t, k, true));
                assert!(rest.distance(n) < 1e-6, "t {t}, k {k}: {rest} ≠ {n}");
            }
        }
        // Sheared towards +X: the tangent leans towards s, more with height (k = 2: slope 2t).
        let (n, s) = (Vec3::Y, Vec3::new(1.0, 1.0, 0.0).normalize());
        let tilt = |t: f32| Vec3::from(strand_tangent(n.to_array(), s.to_array(), t, 2.0, true)).angle_between(n);
        assert!(tilt(0.0) < 1e-3, "the root stands along n for k > 1");
        assert!(tilt(0.25) > 0.05 && tilt(0.5) > tilt(0.25) && tilt(1.0) > tilt(0.5));
        // Eq. 3.36 at t = 1, k = 2: d = n + 2(s − n), finite differences of the offset agree.
        let offset = |t: f32| n * t + t.powi(2) * (s - n);
        let numeric = ((offset(1.0) - offset(1.0 - 1e-3)) / 1e-3).normalize();
        let at_tip = Vec3::from(strand_tangent(n.to_array(), s.to_array(), 1.0, 2.0, true));
        assert!(at_tip.distance(numeric) < 1e-2, "{at_tip} vs {numeric}");
        assert!(at_tip.x > 0.0 && at_tip.dot(s) > n.dot(s), "leans towards s");
        // Without shearing the scale vector is ignored.
        assert_eq!(strand_tangent(n.to_array(), s.to_array(), 0.5, 2.0, false), n.to_array());
        // An inward scale vector lays the hair flat: no component into the surface.
        let inward = Vec3::from(strand_tangent(n.to_array(), [0.6, -0.8, 0.0], 1.0, 2.0, true));
        assert!(inward.dot(n).abs() < 1e-6 && (inward.length() - 1.0).abs() < 1e-6, "{inward}");
    }

    #[test]
    fn bad_shading_is_refused_naming_the_field() {
        assert!(check(&FurShading::default()).is_ok() && check(&FurShading::off()).is_ok());
        let cases: [(FurShading, &str); 5] = [
            (FurShading { primary_exponent: 0.5, ..Default::default() }, "primary_exponent"),
            (FurShading { secondary_shift: f32::NAN, ..Default::default() }, "secondary_shift"),
            (FurShading { root_occlusion: 1.5, ..Default::default() }, "root_occlusion"),
            (FurShading { tip_color: [1.0, -0.1, 1.0], ..Default::default() }, "tip_color"),
            (FurShading { back_light: f32::INFINITY, ..Default::default() }, "back_light"),
        ];
        for (shading, name) in cases {
            match check(&shading) {
                Err(RenderError::Shading { field, .. }) => assert_eq!(field, name),
                other => panic!("{name}: {other:?}"),
            }
        }
    }
}
