//! The shells' level of detail of one view of a [`FrameUniforms`] (the rule and its levels:
//! `furbake_draw::lod`, docs/design.md "Shell level of detail").

use glam::Vec3;

pub use furbake_draw::lod::{ShellLevel, ShellLod};

use crate::shaders::FrameUniforms;

/// [`furbake_draw::lod::projected_fur_px`] for the camera, viewport and model matrix of `frame`.
pub fn projected_fur_px(frame: &FrameUniforms, center: Vec3, radius: f32, fur_length_m: f32) -> Option<f32> {
    let [width, height] = frame.viewport();
    furbake_draw::lod::projected_fur_px(
        frame.view_proj(),
        frame.eye(),
        [width, height],
        frame.model(),
        center,
        radius,
        fur_length_m,
    )
}

#[cfg(test)]
mod tests {
    use glam::Mat4;

    use super::*;

    #[test]
    fn projected_length_follows_distance_and_viewport() {
        let view = crate::View::framing([0.0, 0.0, 0.0], 1.0);
        let frame = view.uniforms(400, 300);
        let near = projected_fur_px(&frame, Vec3::ZERO, 0.5, 0.05).unwrap();
        // Twice the viewport height: twice the pixels.
        let big = projected_fur_px(&view.uniforms(800, 600), Vec3::ZERO, 0.5, 0.05).unwrap();
        assert!((big / near - 2.0).abs() < 1e-3, "{near} {big}");
        // The same pack placed twice as far (model translation along the view): about half.
        let eye = Vec3::from(view.camera.eye);
        let far = frame.with_model(Mat4::from_translation(-eye));
        let far_px = projected_fur_px(&far, Vec3::ZERO, 0.5, 0.05).unwrap();
        assert!(far_px < near * 0.6 && far_px > near * 0.3, "{near} {far_px}");
        // Scaled up by 2: the fur is twice as long (and nearer).
        let scaled = projected_fur_px(&frame.with_model(Mat4::from_scale(Vec3::splat(2.0))), Vec3::ZERO, 0.5, 0.05);
        assert!(scaled.unwrap() > 2.0 * near);
        // No viewport, or the eye inside the bounds: no level of detail.
        let mut none = frame;
        none.viewport = [0.0; 4];
        assert_eq!(projected_fur_px(&none, Vec3::ZERO, 0.5, 0.05), None);
        assert_eq!(projected_fur_px(&frame, eye, 0.5, 0.05), None);
    }
}
