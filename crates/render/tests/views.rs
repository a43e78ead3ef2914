//! Several views in one frame (`RenderSettings::views`, `BladeRenderSettings::views`): one fur renderer
//! and one blade renderer prepared for two cameras into one encoder (`prepare` for view 0,
//! `prepare_view` for view 1) and drawn into two targets before a single submission (split
//! screen, a reflection) draw exactly what each camera draws alone; with one view slot, the second
//! camera is a typed error instead of silently overwriting the first.

use crate::common;

use crate::common::gpu;
use furbake_grass::{ForceField, ForceScene};
use furbake_render::headless::{RenderTarget, read_back};
use furbake_render::{BladeRenderSettings, BladeRenderer, FurRenderer, RenderError, RenderSettings, View};
use furbake_runtime::{Camera, Lighting};
use image::RgbaImage;

const SIZE: u32 = 96;

fn camera(eye: [f32; 3]) -> View {
    View {
        camera: Camera { eye, target: [0.0, 0.2, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 },
        lighting: Lighting::default(),
        bounds_center: [0.0; 3],
        bounds_radius: 1.3,
    }
}

/// What `prepare` / `prepare_view` and `render_view` of one renderer must do for two views.
trait TwoViews {
    fn prepare_view(&self, encoder: &mut wgpu::CommandEncoder, view: usize, frame: &View) -> Result<(), RenderError>;
    fn render_view(&self, pass: &mut wgpu::RenderPass<'_>, view: usize) -> Result<(), RenderError>;
}

impl TwoViews for FurRenderer {
    fn prepare_view(&self, encoder: &mut wgpu::CommandEncoder, view: usize, frame: &View) -> Result<(), RenderError> {
        let uniforms = frame.uniforms(SIZE, SIZE);
        if view == 0 {
            self.prepare(&gpu().queue, encoder, &uniforms);
            return Ok(());
        }
        FurRenderer::prepare_view(self, &gpu().queue, encoder, view, &uniforms)
    }
    fn render_view(&self, pass: &mut wgpu::RenderPass<'_>, view: usize) -> Result<(), RenderError> {
        FurRenderer::render_view(self, pass, view)
    }
}

impl TwoViews for BladeRenderer {
    fn prepare_view(&self, encoder: &mut wgpu::CommandEncoder, view: usize, frame: &View) -> Result<(), RenderError> {
        let uniforms = frame.uniforms(SIZE, SIZE);
        if view == 0 {
            self.prepare(&gpu().queue, encoder, &uniforms);
            return Ok(());
        }
        BladeRenderer::prepare_view(self, &gpu().queue, encoder, view, &uniforms)
    }
    fn render_view(&self, pass: &mut wgpu::RenderPass<'_>, view: usize) -> Result<(), RenderError> {
        BladeRenderer::render_view(self, pass, view)
    }
}

/// Both views prepared into one encoder, then drawn into a target each, one submission.
fn split_screen(renderer: &dyn TwoViews, views: [&View; 2]) -> Result<[RgbaImage; 2], RenderError> {
    let g = gpu();
    let targets = [0, 1].map(|_| RenderTarget::new(&g.device, SIZE, SIZE).unwrap());
    let mut encoder = g.device.create_command_encoder(&Default::default());
    for (k, view) in views.iter().enumerate() {
        renderer.prepare_view(&mut encoder, k, view)?;
    }
    for (k, target) in targets.iter().enumerate() {
        let mut pass = target.begin_pass(&mut encoder, "split screen", Some(RenderSettings::default().background));
        renderer.render_view(&mut pass, k)?;
    }
    g.queue.submit([encoder.finish()]);
    Ok(targets.map(|t| read_back(&g.device, &g.queue, &t).unwrap()))
}

#[test]
fn one_fur_renderer_draws_two_views_in_one_frame() {
    let g = gpu();
    let asset = common::furry_sphere(12, 16, 8, 32, 0.15);
    let (a, b) = (camera([0.0, 0.8, 3.2]), camera([2.8, 1.6, -1.2]));
    let two = RenderSettings { views: 2, ..Default::default() };
    let renderer = FurRenderer::new(g.pipelines(), &g.queue, &asset, &two, &RenderTarget::desc()).unwrap();
    let [left, right] = split_screen(&renderer, [&a, &b]).unwrap();
    let alone = |view: &View| {
        furbake_render::headless::render_image(g, &asset, &RenderSettings::default(), view, SIZE, SIZE).unwrap()
    };
    assert!(left == alone(&a), "view 0 draws its own camera");
    assert!(right == alone(&b), "view 1 draws its own camera, not view 0's");
    assert!(left != right);
    // One view slot: the second camera is refused, not written over the first.
    let one =
        FurRenderer::new(g.pipelines(), &g.queue, &asset, &RenderSettings::default(), &RenderTarget::desc()).unwrap();
    assert!(matches!(split_screen(&one, [&a, &b]), Err(RenderError::Parameter { .. })));
    let bad = RenderSettings { views: 0, ..Default::default() };
    assert!(FurRenderer::new(g.pipelines(), &g.queue, &asset, &bad, &RenderTarget::desc()).is_err());
}

#[test]
fn one_blade_renderer_draws_two_views_in_one_frame() {
    let g = gpu();
    let (table, field) = (common::blade_table(100), common::blade_patch(150.0));
    let blades = |views| {
        let settings = BladeRenderSettings { views, ..BladeRenderSettings::default() };
        let r = BladeRenderer::new(g.pipelines(), &g.queue, &field, &table, &settings, &RenderTarget::desc()).unwrap();
        let mut forces = ForceField::new(field.grid);
        forces.update(&ForceScene::default());
        r.set_force_field(&g.queue, &forces).unwrap();
        r
    };
    let (a, b) = (camera([0.0, 0.5, 1.8]), camera([1.6, 1.4, 0.4]));
    let [left, right] = split_screen(&blades(2), [&a, &b]).unwrap();
    let one = blades(1);
    let alone = |view: &View| {
        let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
        one.render_to(&g.device, &g.queue, &target, view, Some(RenderSettings::default().background)).unwrap();
        read_back(&g.device, &g.queue, &target).unwrap()
    };
    assert!(left == alone(&a), "view 0: its own camera and culling");
    assert!(right == alone(&b), "view 1: its own camera and culling, not view 0's");
    assert!(left != right);
    assert!(matches!(split_screen(&one, [&a, &b]), Err(RenderError::Parameter { .. })));
}
