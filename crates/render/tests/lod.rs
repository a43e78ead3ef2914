//! The shells' level of detail (`RenderSettings::lod`, docs/design.md "Shell level of detail"):
//! a view where the fur projects short draws fewer layers, the picture it draws stays close to
//! the full count's (the stacking keeps the coat's opacity), and moving the camera across a
//! change of level changes the picture gradually, not in one jump.

use std::sync::OnceLock;

use crate::common::{furry_sphere, gpu};
use furbake_render::headless::{RenderTarget, read_back};
use furbake_render::{FurAsset, FurRenderer, RenderSettings, ShellLod, View};
use furbake_runtime::{Camera, Lighting};
use image::RgbaImage;

const SIZE: u32 = 96;

fn sphere() -> &'static FurAsset {
    static A: OnceLock<FurAsset> = OnceLock::new();
    A.get_or_init(|| furry_sphere(12, 24, 16, 64, 0.08))
}

/// The sphere seen from `distance` metres with a narrow lens, so it stays a good size in the
/// image while its fur projects to a few pixels.
fn view(distance: f32) -> View {
    View {
        camera: Camera { eye: [0.0, 0.3 * distance, distance], target: [0.0; 3], up: [0.0, 1.0, 0.0], fov_y_deg: 12.0 },
        lighting: Lighting::default(),
        bounds_center: [0.0; 3],
        bounds_radius: 1.2,
    }
}

fn renderer(lod: Option<ShellLod>) -> FurRenderer {
    let settings = RenderSettings { lod, ..Default::default() };
    FurRenderer::new(gpu().pipelines(), &gpu().queue, sphere(), &settings, &RenderTarget::desc()).unwrap()
}

fn draw(renderer: &FurRenderer, view: &View) -> (RgbaImage, u32) {
    let g = gpu();
    let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
    renderer.render_to(&g.device, &g.queue, &target, view).unwrap();
    (read_back(&g.device, &g.queue, &target).unwrap(), renderer.layers_in_view(0).unwrap())
}

/// Mean absolute difference of two images, per channel in [0, 1].
fn mean_diff(a: &RgbaImage, b: &RgbaImage) -> f64 {
    let sum: u64 = a.as_raw().iter().zip(b.as_raw()).map(|(x, y)| x.abs_diff(*y) as u64).sum();
    sum as f64 / (a.as_raw().len() as f64 * 255.0)
}

// A steep slope so that levels change within a few metres of camera distance.
const LOD: ShellLod = ShellLod { layers_per_px: 2.0, min_layers: 4 };

#[test]
fn far_fur_draws_fewer_layers_and_keeps_its_look() {
    let (lod, full) = (renderer(Some(LOD)), renderer(None));
    // Near: the fur projects long, every layer is drawn.
    let (_, near_layers) = draw(&lod, &view(8.0));
    assert_eq!(near_layers, 16);
    // Far: fewer layers, down to the floor.
    let (far, far_layers) = draw(&lod, &view(40.0));
    let (far_full, full_layers) = draw(&full, &view(40.0));
    assert_eq!(full_layers, 16, "without a level of detail every layer is drawn");
    assert!((LOD.min_layers..16).contains(&far_layers), "{far_layers} layers far away");
    // Where fewer layers are drawn the coat keeps its tone: the difference to the full count is
    // a small fraction of what removing the fur altogether changes.
    let bare = RenderSettings { shell_layers: Some(0), lod: None, ..Default::default() };
    let bare = FurRenderer::new(gpu().pipelines(), &gpu().queue, sphere(), &bare, &RenderTarget::desc()).unwrap();
    let (skin, _) = draw(&bare, &view(40.0));
    let (lod_error, fur_weight) = (mean_diff(&far, &far_full), mean_diff(&skin, &far_full));
    assert!(fur_weight > 0.002, "the fur must show at this distance: {fur_weight}");
    assert!(lod_error < 0.25 * fur_weight, "level of detail changed the image by {lod_error}, the fur is {fur_weight}");
}

#[test]
fn crossing_a_level_changes_the_picture_gradually() {
    // Step the camera out in small increments across the level change 16 → 8: how far the
    // level-of-detail picture is from the full count's grows gradually, with no step that jumps
    // (a level switching without its fade would change the difference at once).
    let (lod, full) = (renderer(Some(LOD)), renderer(None));
    let mut layers_seen = Vec::new();
    let mut errors = Vec::new();
    for i in 0..40 {
        let d = 3.0 + i as f32 * 0.25;
        let (image, layers) = draw(&lod, &view(d));
        let (image_full, _) = draw(&full, &view(d));
        layers_seen.push(layers);
        errors.push(mean_diff(&image, &image_full));
    }
    assert!(layers_seen.contains(&16) && layers_seen.contains(&8), "no level change crossed: {layers_seen:?}");
    let worst = errors.iter().cloned().fold(0.0, f64::max);
    let jump = errors.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0, f64::max);
    assert!(worst > 0.0, "the levels drew the full count everywhere");
    assert!(
        jump < 0.25 * worst,
        "a level change jumped by {jump} (largest difference {worst}): {errors:?} {layers_seen:?}"
    );
}

#[test]
fn a_frame_without_a_viewport_draws_every_layer() {
    let lod = renderer(Some(LOD));
    let g = gpu();
    let mut encoder = g.device.create_command_encoder(&Default::default());
    let frame = view(40.0).uniforms(SIZE, SIZE).with_viewport(0, 0);
    lod.prepare(&g.queue, &mut encoder, &frame);
    assert_eq!(lod.layers_in_view(0).unwrap(), 16);
    assert_eq!(furbake_render::testing::shell_level(&lod, &frame), furbake_render::testing::ShellLevel::full(16));
    drop(encoder);
}
