//! The rendering report's claims at a small scale (`furbake_report::rendering`; the full-size
//! numbers are in docs/rendering-accuracy.md): the reference traces the bake's own hairs, converges
//! as samples are added, covers a flat patch seen from above as much as the hairs' projected area
//! does, furbake's shells approach it as layers are added and with the stacking exponents, the
//! near side of a coat covers its far side at a silhouette, and the default level of detail draws
//! the measured knee.

use furbake_bake::BakeSettings;
use furbake_bake::volume::slice_shell_atlas;
use furbake_render::RenderSettings;
use furbake_report::rendering::gpu::{MeasuringGpu, ReportTarget};
use furbake_report::rendering::reference::{ReferenceSettings, render_reference};
use furbake_report::rendering::report::{FinMode, background, reference_camera, reference_of, render_settings};
use furbake_report::rendering::scenes::{FurScene, SceneKind, bake_scene};
use furbake_report::rendering::score::score;
use furbake_report::rendering::shade::ShadeSettings;
use furbake_runtime::scene::FurShading;

fn fixtures() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

/// The `fur` preset with a 32² tile (hairs four times as thick relative to the fur: quick).
fn small_fur() -> BakeSettings {
    let mut s = BakeSettings::preset("fur").unwrap();
    s.volume.resolution = 32;
    s
}

/// The report's GPU drawing into `Rgba32Float`, so that blending many faint layers rounds nothing
/// away (lavapipe blends into it).
fn float_target_gpu() -> MeasuringGpu {
    let mut gpu = MeasuringGpu::new().unwrap();
    assert_eq!(gpu.set_target(ReportTarget::Float32), ReportTarget::Float32, "lavapipe blends into Rgba32Float");
    gpu
}

fn patch(settings: &BakeSettings) -> FurScene {
    bake_scene(SceneKind::Patch, &fixtures(), settings).unwrap()
}

#[test]
fn the_reference_traces_the_hairs_the_atlas_was_sliced_from() {
    let scene = patch(&small_fur());
    let atlas = scene.asset.shells();
    let hairs = scene.volume.hairs();
    assert!(hairs.len() > 100, "{} hairs", hairs.len());
    let again = slice_shell_atlas(&atlas.params, hairs, atlas.seed, atlas.fur_length_m);
    assert_eq!(again.alpha.len(), atlas.alpha.len());
    assert!(again.alpha == atlas.alpha, "re-slicing the regrown hairs gives the atlas's bytes");
}

#[test]
fn more_samples_per_pixel_change_the_reference_less() {
    // Two seeds at k² samples: their difference is the sampling noise, which falls about as 1/k.
    let scene = patch(&small_fur());
    let view = scene.view(45.0, 12.0 * scene.fur_length_m);
    let light = ShadeSettings::new(&view.uniforms(1, 1), FurShading::default());
    let camera = reference_camera(&view);
    let noise = |strata: u32| {
        let image = |seed| {
            let s = ReferenceSettings { strata, seed, ..Default::default() };
            render_reference(&scene.volume, &camera, &light, 24, 24, &s).unwrap()
        };
        let (a, b) = (image(1), image(2));
        let diff: f32 = a.rgb.iter().zip(&b.rgb).map(|(p, q)| (*p - *q).abs().element_sum()).sum();
        diff / a.rgb.len() as f32
    };
    let (coarse, fine) = (noise(2), noise(6));
    assert!(coarse > 0.0, "different seeds sample differently");
    assert!(fine < 0.6 * coarse, "36 samples per pixel differ by {fine}, 4 by {coarse}");
}

#[test]
fn seen_from_above_the_hairs_cover_their_projected_area() {
    // Straight, untapered hairs of one coat seen along the normal from far away: the share of
    // samples that hit a hair is the share of the tile their discs cover (counted here on a fine
    // grid of the tile, wrapping at its border, independently of the marcher).
    let mut settings = small_fur();
    settings.volume.undercoat = None;
    settings.volume.coat.max_deviation_texels = 0.0;
    settings.volume.coat.taper = 0.0;
    let scene = patch(&settings);
    let hairs = scene.volume.hairs();
    let res = hairs.resolution as f32;
    let grid = 512;
    let mut inside = 0u32;
    for gy in 0..grid {
        for gx in 0..grid {
            let p = glam::Vec2::new((gx as f32 + 0.5) / grid as f32 * res, (gy as f32 + 0.5) / grid as f32 * res);
            let hit = (0..hairs.len()).any(|i| {
                let mut d = glam::Vec2::new(hairs.root_x[i], hairs.root_y[i]) - p;
                d -= res * (d / res).round();
                d.length() < hairs.radius_texels[i]
            });
            inside += u32::from(hit);
        }
    }
    let area = inside as f32 / (grid * grid) as f32;
    // 50 m up with a 0.4° field of view: rays within 0.2 mrad of the normal, about 0.35 m of the
    // patch (many tile repeats of 4 fur lengths) in view.
    let mut view = scene.view(0.0, 50.0);
    view.camera.fov_y_deg = 0.4;
    let light = ShadeSettings::new(&view.uniforms(1, 1), FurShading::default());
    let s = ReferenceSettings { strata: 3, ..Default::default() };
    let image = render_reference(&scene.volume, &reference_camera(&view), &light, 48, 48, &s).unwrap();
    assert!(image.coverage.iter().all(|&c| c == 1.0), "the patch fills the view");
    let covered = image.hair_coverage.iter().sum::<f32>() / image.hair_coverage.len() as f32;
    assert!((0.1..0.6).contains(&area), "disc area share {area}");
    assert!((covered - area).abs() < 0.03, "hairs cover {covered} of the view, their discs {area} of the tile");
}

#[test]
fn shells_approach_the_reference_and_the_stacking_brings_them_closer() {
    // Small: a 64² view of the patch 12 fur lengths away, 16 samples per pixel, the `fur` preset's
    // own 128² tile (with a 32² tile the hairs are a third of their length wide, and seen along
    // them the 4 shells beat 16: the anti-aliased disc edges compound over the stacked layers,
    // docs/rendering-accuracy.md). Along the hairs 16 shells beat 4; at 0° and 45° the stacking
    // exponents (docs/design.md "Shell opacity") lower the error at both counts against blending
    // each layer's alpha as it is. (Fins do not yet lower it at 70°: docs/rendering-accuracy.md.)
    let scene = patch(&BakeSettings::preset("fur").unwrap());
    let gpu = MeasuringGpu::new().unwrap();
    let flip = |angle: f32, shells: u32, stacking_correction: bool, reference: &_| {
        let view = scene.view(angle, 12.0 * scene.fur_length_m);
        let settings = RenderSettings { stacking_correction, ..render_settings(shells, FinMode::Silhouette) };
        let frame = gpu.measure(&scene.asset, &settings, &view, 64, 64, 1).unwrap();
        score(reference, &frame.image, background()).0.flip_mean
    };
    let mut checked = 0;
    for angle in [0.0, 45.0] {
        let reference = reference_of(&scene, &scene.view(angle, 12.0 * scene.fur_length_m), 64, 4).unwrap();
        for shells in [4, 16] {
            let (plain, stacked) = (flip(angle, shells, false, &reference), flip(angle, shells, true, &reference));
            assert!(stacked < plain, "at {angle}° with {shells} shells: FLIP {plain} plain, {stacked} stacked");
            checked += 1;
        }
        if angle == 0.0 {
            let (four, sixteen) = (flip(angle, 4, true, &reference), flip(angle, 16, true, &reference));
            assert!(sixteen < four, "at {angle}°: FLIP {four} with 4 shells, {sixteen} with 16");
        }
    }
    assert_eq!(checked, 4);
}

#[test]
fn at_an_oblique_view_the_error_falls_as_shells_are_added() {
    // docs/rendering-accuracy.md "Does the error fall as shells are added": the patch at 45°,
    // drawn into a single-float target, scores lower (or within 2 %) at every doubling from 8 to
    // 64 shells. The two mistakes this holds off, both measured there: blended shells that skipped
    // texels of alpha up to 0.02 (a distant coat's mip-averaged tips; the stack came out clearer
    // than the hair volume, more so the more layers) and layers shaded at their slab's top (too
    // bright at 8 layers, too dark at 64: the error fell to 8 shells and rose after).
    let scene = patch(&BakeSettings::preset("fur").unwrap());
    let gpu = float_target_gpu();
    let view = scene.view(45.0, 16.0 * scene.fur_length_m);
    let reference = reference_of(&scene, &view, 64, 4).unwrap();
    let errors: Vec<(u32, f32)> = [8, 16, 32, 64]
        .into_iter()
        .map(|shells| {
            let frame = gpu.measure(&scene.asset, &render_settings(shells, FinMode::Silhouette), &view, 64, 64, 1);
            (shells, score(&reference, &frame.unwrap().image, background()).0.flip_mean)
        })
        .collect();
    for pair in errors.windows(2) {
        assert!(pair[1].1 <= 1.02 * pair[0].1, "FLIP by shell count: {errors:?}");
    }
    assert!(errors[3].1 < 0.95 * errors[0].1, "64 shells below 8: {errors:?}");
}

#[test]
fn at_a_silhouette_the_near_side_of_the_coat_covers_the_far_side() {
    // docs/design.md "Shell order": the sphere at 70°, its limb in view, where a ray crosses the
    // coat twice. Blended shells draw their back faces (the coat's far side) before their front
    // faces; drawn in one pass, innermost layer first, the far side's outer layers blended over
    // the near side's inner ones and the limb came out light where the hair volume is not.
    // Measured on lavapipe (64², 12 fur lengths, 16 shells): FLIP 0.0484, and 0.0709 in one pass.
    let scene = bake_scene(SceneKind::Sphere, &fixtures(), &BakeSettings::preset("fur").unwrap()).unwrap();
    let gpu = float_target_gpu();
    let view = scene.view(70.0, 12.0 * scene.fur_length_m);
    let reference = reference_of(&scene, &view, 64, 4).unwrap();
    let frame = gpu.measure(&scene.asset, &render_settings(16, FinMode::Silhouette), &view, 64, 64, 1).unwrap();
    let flip = score(&reference, &frame.image, background()).0.flip_mean;
    println!("sphere at 70°, 16 shells: FLIP {flip:.4}");
    assert!(flip < 0.06, "FLIP {flip}");
}

#[test]
fn the_default_level_of_detail_draws_the_measured_knee() {
    // docs/rendering-accuracy.md "Level of detail: the knee": at each measured fur length the
    // default ShellLod draws the knee's count from a maximum of 64 (the sweep's largest).
    use furbake_render::ShellLod;
    use furbake_report::rendering::report::MEASURED_KNEES;
    for (px, knee) in MEASURED_KNEES {
        assert_eq!(ShellLod::default().layers(64, px), (knee, 1.0), "fur {px} px long");
    }
}
