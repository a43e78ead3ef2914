//! Several lights and a hemisphere ambient (docs/design.md "Lights"; `shaders/lighting.wgsl`) on
//! whatever adapter the machine has (lavapipe without a GPU; never skips), as properties of a
//! furry unit sphere drawn with the default strand shading on black:
//! (a) light adds up: the frame lit by a key and a fill light together is, in linear RGB, the sum
//!     of the frames lit by each alone;
//! (b) a point light falls off as 1/d²: one 200 m away with intensity 200² draws what a directional
//!     light of intensity 1 from the same side draws;
//! (c) a point light beyond its range lights nothing (the frame is the ambient-only frame, bit for
//!     bit), and one within it lights the side facing it;
//! (d) the hemisphere ambient colours surfaces facing up with `sky` and those facing down with
//!     `ground`;
//! (e) the `[light]` shorthand draws bit for bit what its `[[lights]]`/`[ambient]` form draws.
//! Renders stay small (96², 8 layers).

use crate::common;

use std::sync::{Arc, OnceLock};

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::ImportSettings;
use furbake_render::headless::render_image;
use furbake_render::{FurAsset, RenderSettings, View};
use furbake_runtime::{Ambient, Camera, LightSource, Lighting, Scene};
use image::RgbaImage;

const SIZE: u32 = 96;
const FUR_M: f32 = 0.15;

fn sphere() -> &'static FurAsset {
    static SPHERE: OnceLock<FurAsset> = OnceLock::new();
    SPHERE.get_or_init(|| common::furry_sphere(16, 24, 8, 32, FUR_M))
}

fn render(lighting: Lighting) -> RgbaImage {
    let view = View {
        camera: Camera { eye: [0.0, 0.0, 4.0], target: [0.0; 3], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 },
        lighting,
        bounds_center: [0.0; 3],
        bounds_radius: 1.0 + FUR_M,
    };
    let settings = RenderSettings { background: [0.0, 0.0, 0.0, 1.0], ..Default::default() };
    render_image(gpu(), sphere(), &settings, &view, SIZE, SIZE).unwrap()
}

const DARK: Ambient = Ambient { sky: [0.0; 3], ground: [0.0; 3] };

fn lit(sources: &[LightSource], ambient: Ambient) -> RgbaImage {
    render(Lighting::new(sources, ambient).unwrap())
}

fn directional(direction: [f32; 3], color: [f32; 3], intensity: f32) -> LightSource {
    LightSource::Directional { direction, color, intensity }
}

fn linear(c: u8) -> f64 {
    let c = c as f64 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Mean linear luminance-ish (channel mean) of the pixels in columns `x0..x1`.
fn mean_linear(image: &RgbaImage, x0: u32, x1: u32) -> f64 {
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in 0..SIZE {
        for x in x0..x1 {
            let p = image.get_pixel(x, y);
            sum += (0..3).map(|c| linear(p[c])).sum::<f64>() / 3.0;
            n += 1.0;
        }
    }
    sum / n
}

#[test]
fn light_adds_up() {
    let key = directional([-1.0, -0.4, -0.6], [1.0, 0.95, 0.9], 0.6);
    let fill = LightSource::Point { position: [3.0, 1.0, 2.0], color: [0.6, 0.7, 1.0], intensity: 4.0, range_m: 0.0 };
    let (a, b, both) = (lit(&[key], DARK), lit(&[fill], DARK), lit(&[key, fill], DARK));
    let mut errors = Vec::new();
    for ((pa, pb), pc) in a.pixels().zip(b.pixels()).zip(both.pixels()) {
        for c in 0..3 {
            let (sa, sb, sc) = (linear(pa[c]), linear(pb[c]), linear(pc[c]));
            if sa + sb < 0.9 {
                errors.push((sc - (sa + sb)).abs());
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let p99 = errors[errors.len() * 99 / 100];
    assert!(mean_linear(&a, 0, SIZE) > 0.01 && mean_linear(&b, 0, SIZE) > 0.01, "both lights light the sphere");
    // The framebuffer stores 8-bit sRGB after every blended shell, so each of the 8 layers
    // rounds by up to half a step (about 0.002 in linear units at mid-grey): a few pixels of
    // the rim, where many layers overlap, reach 0.04; most are within rounding. The 99th
    // percentile was 0.0118; blending every faint texel (no 0.02 alpha threshold) made it 0.0122
    // and fins shaded as the coat's top (brighter colours at the rim, whose 8-bit steps are
    // larger in linear units) 0.0141.
    assert!(
        p99 < 0.016 && mean < 0.0015,
        "two lights are the sum of each alone: 99th percentile {p99:.4}, mean {mean:.5}"
    );
}

#[test]
fn a_point_light_falls_off_with_the_square_of_the_distance() {
    let toward = glam::Vec3::new(1.0, 0.5, 0.8).normalize();
    let far =
        LightSource::Point { position: (toward * 200.0).to_array(), color: [1.0; 3], intensity: 40000.0, range_m: 0.0 };
    let sun = directional((-toward).to_array(), [1.0; 3], 1.0);
    let (point, directional) = (lit(&[far], DARK), lit(&[sun], DARK));
    let mut diff = 0.0;
    let mut max = 0u8;
    for (p, q) in point.pixels().zip(directional.pixels()) {
        for c in 0..3 {
            let d = p[c].abs_diff(q[c]);
            max = max.max(d);
            diff += d as f64;
        }
    }
    let mean = diff / (3 * SIZE * SIZE) as f64;
    assert!(mean_linear(&directional, 0, SIZE) > 0.02, "the light reaches the sphere");
    // Across the sphere the point light's direction differs by up to atan(1.15/200) ≈ 0.3° and
    // its falloff by (200/198.85)² ≈ 1.2 %.
    assert!(
        mean < 0.5 && max <= 8,
        "a point light 200 m away with intensity 200² is a unit directional light: mean {mean:.3}/255, max {max}/255"
    );
}

#[test]
fn a_point_light_reaches_only_its_range() {
    let ambient = Ambient { sky: [0.1; 3], ground: [0.1; 3] };
    let beside = |range_m| LightSource::Point { position: [3.0, 0.0, 0.0], color: [1.0; 3], intensity: 6.0, range_m };
    let none = lit(&[], ambient);
    assert_eq!(lit(&[beside(1.5)], ambient).as_raw(), none.as_raw(), "beyond its range a point light adds nothing");
    let within = lit(&[beside(20.0)], ambient);
    let (left, right) = (mean_linear(&within, 0, SIZE / 3), mean_linear(&within, 2 * SIZE / 3, SIZE));
    let (left0, right0) = (mean_linear(&none, 0, SIZE / 3), mean_linear(&none, 2 * SIZE / 3, SIZE));
    assert!(right > 3.0 * right0, "the side facing the light is lit: {right:.4} against {right0:.4} unlit");
    assert!(left < left0 * 1.2 + 0.002, "the far side stays ambient: {left:.4} against {left0:.4}");
}

#[test]
fn the_hemisphere_ambient_is_sky_above_and_ground_below() {
    let image = lit(&[], Ambient { sky: [0.05, 0.1, 0.4], ground: [0.3, 0.15, 0.02] });
    let band = |y0: u32, y1: u32| {
        let mut rgb = [0.0f64; 3];
        for y in y0..y1 {
            for x in SIZE / 3..2 * SIZE / 3 {
                let p = image.get_pixel(x, y);
                for c in 0..3 {
                    rgb[c] += linear(p[c]);
                }
            }
        }
        rgb
    };
    let (top, bottom) = (band(SIZE / 6, SIZE / 3), band(2 * SIZE / 3, 5 * SIZE / 6));
    assert!(top[2] > 2.0 * top[0], "the top is sky-blue: {top:?}");
    assert!(bottom[0] > 2.0 * bottom[2], "the bottom is ground-brown: {bottom:?}");
}

#[test]
fn the_light_shorthand_is_its_long_form() {
    // Values exact in binary, so the shorthand's (1 − a) · color is exactly the long form's.
    let scene = |lights: &str| {
        let text = format!("{lights}\n[[packs]]\nname = \"s\"\npath = \"s.fbk\"\n");
        Scene::from_toml_str(&text, "scene.toml".as_ref(), ".".as_ref()).unwrap().lighting()
    };
    let short = scene("[light]\ndirection = [-0.3, -1.0, 0.5]\ncolor = [1.0, 0.5, 0.75]\nambient = 0.25");
    let long = scene(
        "[[lights]]\ntype = \"directional\"\ndirection = [-0.3, -1.0, 0.5]\ncolor = [0.75, 0.375, 0.5625]\n\
         [ambient]\nsky = [0.25, 0.125, 0.1875]\nground = [0.25, 0.125, 0.1875]",
    );
    assert_eq!(short, long);
    assert_eq!(render(short).as_raw(), render(long).as_raw());
    let default = scene("");
    assert_eq!(default, Lighting::default(), "no light keys: the studio default, not the [light] default");
}

/// The GPU cost of the lights (docs/performance.md "Lights"): the bundled Fox (`fur` preset, 16
/// layers of 128²) at 640×480 in `View::framing`, lit by the one `[light]` default, by the studio
/// default (two lights) and by four lights, each through a renderer with that many light slots,
/// frame by frame in turn (so all see the same machine
/// load), each frame waited for; median of 9 after 2 warm-up frames. A measurement:
/// `cargo test -p furbake-render --test render -- --ignored --nocapture light_count_frame_cost`.
// Ignored in `make test`: it asserts nothing (speed belongs in docs/performance.md, not in timed
// tests) and its waited-for frames take tens of seconds on lavapipe.
#[test]
#[ignore = "a measurement, not a check"]
fn light_count_frame_cost() {
    use std::time::Instant;
    let g = gpu();
    let fox = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let imported = furbake_import::import_gltf(&fox, &ImportSettings::default()).unwrap();
    let baked = bake(&imported, "fox", &BakeSettings::preset("fur").unwrap().plan().unwrap(), &mut NoProgress).unwrap();
    let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
    let asset = FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins).unwrap();
    let (center, radius) = asset.bounding_sphere();
    let studio = Lighting::default();
    let mut four = studio.sources().to_vec();
    four.push(directional([0.0, -1.0, 0.3], [0.3, 0.3, 0.3], 1.0));
    four.push(LightSource::Point { position: [1.0, 1.0, 1.0], color: [1.0; 3], intensity: 0.5, range_m: 0.0 });
    let lightings = [
        ("one ([light] default)", Lighting::from(furbake_runtime::Light::default())),
        ("studio (two)", studio),
        ("four", Lighting::new(&four, studio.ambient).unwrap()),
    ];
    // Each renderer with as many light slots as its lighting has lights, as scenes build them.
    let renderers: Vec<_> = lightings
        .iter()
        .map(|(_, lighting)| {
            let settings = RenderSettings {
                light_slots: furbake_render::RenderSettings::light_slots_for(lighting),
                ..Default::default()
            };
            furbake_render::FurRenderer::new(
                g.pipelines(),
                &g.queue,
                &asset,
                &settings,
                &furbake_render::headless::RenderTarget::desc(),
            )
            .unwrap()
        })
        .collect();
    let target = furbake_render::headless::RenderTarget::new(&g.device, 640, 480).unwrap();
    let mut times = vec![Vec::new(); lightings.len()];
    for frame in 0..11 {
        for (k, ((_, lighting), renderer)) in lightings.iter().zip(&renderers).enumerate() {
            let view = View { lighting: *lighting, ..View::framing(center, radius) };
            let start = Instant::now();
            renderer.render_to(&g.device, &g.queue, &target, &view).unwrap();
            g.device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
            if frame >= 2 {
                times[k].push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
    }
    let medians: Vec<f64> = times
        .into_iter()
        .map(|mut t| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        })
        .collect();
    for ((name, _), m) in lightings.iter().zip(&medians) {
        println!("Fox 640×480, {name}: {m:.1} ms, {:.2} × one light", m / medians[0]);
    }
}
