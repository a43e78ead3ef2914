//! Render tests on whatever adapter the machine has (Mesa lavapipe on CI machines without a
//! GPU). They never skip: without an adapter they fail with the command that installs lavapipe.
//! Properties checked: the fur silhouette extends beyond the bare skin's, nothing is drawn below
//! the surface (also when the scale vectors point into it), the eq. 3.36 shear follows the
//! scale-vector buffer, the image is not blank; plus a comparison with a committed reference
//! image of the Lambert × self-shadow path, drawn with the strand shading off (regenerate with
//! `FURBAKE_BLESS=1 cargo test -p furbake-render --test render render::`).
//! Renders stay small (≤ 256², ≤ 16 layers): lavapipe costs ~0.3 s per 256²×64-layer frame.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_render::headless::{HeadlessGpu, RenderTarget, read_back, render_image};
use furbake_render::{FurAsset, FurRenderer, FurShading, RenderSettings, ShellBlend, View};
use furbake_runtime::{Camera, Light};
use image::RgbaImage;

const SIZE: u32 = 128;
const TRANSPARENT: [f32; 4] = [0.0, 0.0, 0.0, 0.0];

/// Bakes `gltf` with 16 layers of 64² shells and the given fur length.
fn bake_asset(gltf: &[u8], name: &str, fur_length_m: f32) -> FurAsset {
    let imported = import_gltf_slice(gltf, name, None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    settings.volume.layers = 16;
    settings.volume.resolution = 64;
    settings.shells.fur_length_m = Some(fur_length_m);
    let baked = bake(&imported, name, &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
    FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins).unwrap()
}

/// A unit sphere with fur 0.15 m long.
fn sphere() -> &'static FurAsset {
    static SPHERE: OnceLock<FurAsset> = OnceLock::new();
    SPHERE.get_or_init(|| bake_asset(&testmesh::uv_sphere(16, 24, 1.0).gltf, "sphere.gltf", 0.15))
}

/// The sphere in `View::framing`, lit by the one `[light]` default (`Light::default`) the
/// committed reference was made with.
fn sphere_view() -> View {
    let (center, radius) = sphere().bounding_sphere();
    View { lighting: furbake_runtime::Light::default().into(), ..View::framing(center, radius) }
}

fn covered(image: &RgbaImage) -> usize {
    image.pixels().filter(|p| p[3] > 0).count()
}

fn out_dir() -> PathBuf {
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn fur_silhouette_extends_beyond_the_bare_skin() {
    let mut checked = 0;
    for (blend, alpha_threshold) in [(ShellBlend::AlphaBlend, 0.02), (ShellBlend::AlphaTest, 0.4)] {
        let base = RenderSettings { background: TRANSPARENT, blend, alpha_threshold, ..Default::default() };
        let render = |layers| {
            let settings = RenderSettings { shell_layers: Some(layers), ..base };
            render_image(gpu(), sphere(), &settings, &sphere_view(), SIZE, SIZE).unwrap()
        };
        let (bare, furry) = (render(0), render(16));
        bare.save(out_dir().join("sphere_bare.png")).unwrap();
        furry.save(out_dir().join(format!("sphere_fur16_{blend:?}.png"))).unwrap();
        let (n_bare, n_fur) = (covered(&bare), covered(&furry));
        // The skin of a unit sphere fills a disc; 0.15 m of fur widens its radius by up to 15 %,
        // so the covered area grows by up to 32 %. Sparse hair tips cover part of that ring: ask 5 %.
        assert!(n_bare > 2000, "the bare sphere covers {n_bare} pixels");
        assert!(n_fur as f64 > n_bare as f64 * 1.05, "{blend:?}: fur covers {n_fur} pixels, bare skin {n_bare}");
        // Every skin pixel stays covered once fur is drawn over it.
        let lost = bare.pixels().zip(furry.pixels()).filter(|(b, f)| b[3] > 0 && f[3] == 0).count();
        assert_eq!(lost, 0, "{blend:?}: {lost} skin pixels became empty under fur");
        checked += 1;
    }
    assert_eq!(checked, 2);
}

#[test]
fn the_image_is_lit_shadowed_and_not_blank() {
    let image = render_image(gpu(), sphere(), &RenderSettings::default(), &sphere_view(), SIZE, SIZE).unwrap();
    let bg = image.get_pixel(0, 0).0;
    let drawn: Vec<_> = image.pixels().filter(|p| p.0 != bg).collect();
    assert!(drawn.len() > (SIZE * SIZE / 5) as usize, "only {} pixels differ from the background", drawn.len());
    let luma = |p: &image::Rgba<u8>| (p[0] as u32 + p[1] as u32 + p[2] as u32) / 3;
    let (lo, hi) = drawn.iter().fold((255, 0), |(lo, hi), p| (lo.min(luma(p)), hi.max(luma(p))));
    // Lambert and the self-shadow table spread the shading over a wide range of values.
    assert!(hi - lo > 100, "luma spans only {lo}..{hi}");
    let mut distinct: Vec<u32> = drawn.iter().map(|p| luma(p)).collect();
    distinct.sort_unstable();
    distinct.dedup();
    assert!(distinct.len() > 50, "only {} distinct grey levels: not a furry render", distinct.len());
}

/// A 2 m plane (Y up) seen exactly edge-on from the side: the plane projects onto the horizon
/// row, so anything drawn below that row would be fur inside (under) the surface.
fn edge_on(scale_vectors: Option<Vec<[f32; 3]>>) -> (RgbaImage, u32) {
    static PLANE: OnceLock<FurAsset> = OnceLock::new();
    let plane = PLANE.get_or_init(|| bake_asset(&testmesh::plane_with_bare_region(8, 2.0).gltf, "plane.gltf", 0.3));
    let view = View {
        camera: Camera { eye: [0.0, 0.0, 4.0], target: [0.0, 0.0, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 },
        lighting: Light::default().into(),
        bounds_center: [0.0, 0.0, 0.0],
        bounds_radius: 1.6,
    };
    let settings = RenderSettings { background: TRANSPARENT, ..Default::default() };
    let g = gpu();
    let renderer = FurRenderer::new(g.pipelines(), &g.queue, plane, &settings, &RenderTarget::desc()).unwrap();
    if let Some(s) = scale_vectors {
        renderer.set_scale_vectors(&g.queue, &s).unwrap();
    }
    let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
    renderer.render_to(&g.device, &g.queue, &target, &view).unwrap();
    (read_back(&g.device, &g.queue, &target).unwrap(), plane.mesh().positions.len() as u32)
}

fn rows_covered(image: &RgbaImage) -> (u32, u32, usize) {
    let (mut top, mut bottom, mut n) = (u32::MAX, 0, 0);
    for (_, y, _) in image.enumerate_pixels().filter(|(_, _, p)| p[3] > 0) {
        top = top.min(y);
        bottom = bottom.max(y);
        n += 1;
    }
    (top, bottom, n)
}

#[test]
fn nothing_is_drawn_below_the_surface_even_with_inward_scale_vectors() {
    let horizon = SIZE / 2; // the eye is at the plane's height, looking straight at it
    let (rest, vertices) = edge_on(None);
    rest.save(out_dir().join("plane_edge_on.png")).unwrap();
    let (top, bottom, n) = rows_covered(&rest);
    assert!(n > 100, "the fins stand above the edge-on plane: {n} pixels");
    assert!(top < horizon - 5, "fur rises above the surface (top row {top})");
    assert!(bottom <= horizon, "pixels drawn below the surface, down to row {bottom} (horizon {horizon})");

    // Scale vectors pointing straight into the surface (s = −n): the shader removes the inward
    // component, so the fur lies flat on the surface and nothing appears below it.
    let (inward, _) = edge_on(Some(vec![[0.0, -1.0, 0.0]; vertices as usize]));
    inward.save(out_dir().join("plane_edge_on_inward.png")).unwrap();
    let (_, bottom, _) = rows_covered(&inward);
    assert!(bottom <= horizon, "inward scale vectors drew fur below the surface, down to row {bottom}");
}

#[test]
fn scale_vectors_shear_the_fur_towards_them() {
    // Eq. 3.36: the outer layers move by t^k (s − n)·L. Tilting every s towards +X moves the fur's
    // covered pixels to the right (the camera looks along −Z with +X to the right).
    let (rest, vertices) = edge_on(None);
    let tilted = glam::Vec3::new(1.0, 1.0, 0.0).normalize().to_array();
    let (sheared, _) = edge_on(Some(vec![tilted; vertices as usize]));
    sheared.save(out_dir().join("plane_edge_on_sheared.png")).unwrap();
    let mean_x = |img: &RgbaImage| {
        let xs: Vec<f64> = img.enumerate_pixels().filter(|(_, _, p)| p[3] > 0).map(|(x, _, _)| x as f64).collect();
        assert!(!xs.is_empty());
        (xs.iter().sum::<f64>() / xs.len() as f64, xs.len())
    };
    let ((x_rest, n_rest), (x_sheared, n_sheared)) = (mean_x(&rest), mean_x(&sheared));
    assert!(x_sheared > x_rest + 1.0, "sheared fur centroid {x_sheared:.1} vs rest {x_rest:.1}");
    // The shear also lowers the tips (length is not preserved, §3.4.2), so no taller image.
    let ((top_rest, _, _), (top_sheared, _, _)) = (rows_covered(&rest), rows_covered(&sheared));
    assert!(top_sheared >= top_rest, "tips rose from row {top_rest} to {top_sheared}");
    assert!(n_rest > 0 && n_sheared > 0);
}

#[test]
fn matches_the_reference_image() {
    // The reference is the Lambert × self-shadow path (made before the strand shading existed),
    // kept reachable with the strand shading off; `fur_shading.rs` checks the strand-shaded frame
    // against it.
    let lambert = RenderSettings { shading: FurShading::off(), ..Default::default() };
    let image = render_image(gpu(), sphere(), &lambert, &sphere_view(), SIZE, SIZE).unwrap();
    let reference_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference/sphere_fur16_128.png");
    image.save(out_dir().join("sphere_fur16_128.png")).unwrap();
    if std::env::var_os("FURBAKE_BLESS").is_some() {
        image.save(&reference_path).unwrap();
    }
    let reference = image::open(&reference_path)
        .unwrap_or_else(|e| panic!("{}: {e} (regenerate with FURBAKE_BLESS=1)", reference_path.display()))
        .to_rgba8();
    assert_eq!(reference.dimensions(), image.dimensions());
    let (far, worst) = pixels_beyond_tolerance(&image, &reference);
    let total = (SIZE * SIZE) as usize;
    assert!(
        far * 100 <= total * MAX_FAR_PERCENT,
        "{far} of {total} pixels differ by more than {CHANNEL_TOLERANCE}/255 (worst {worst})"
    );

    // The tolerance is tight enough to catch a broken effect: the same frame without the
    // self-shadow table must fail it.
    let unshadowed = RenderSettings { self_shadow: false, ..lambert };
    let wrong = render_image(gpu(), sphere(), &unshadowed, &sphere_view(), SIZE, SIZE).unwrap();
    let (far_wrong, _) = pixels_beyond_tolerance(&wrong, &reference);
    assert!(
        far_wrong * 100 > total * MAX_FAR_PERCENT,
        "a render without self-shadow passes as the reference ({far_wrong} far pixels)"
    );
}

// Tolerance: the reference comes from lavapipe, which is deterministic run to run, but other
// drivers and GPUs rasterise edges, filter the R8 mip chain and round sRGB differently. A channel
// may differ by up to 24/255 (one hair texel filtered differently at this size), and up to 3 % of
// the pixels may differ by more (hair tips and silhouette pixels, where coverage is
// all-or-nothing). A wrong effect changes far more (checked above with the shadow table off).
const CHANNEL_TOLERANCE: u8 = 24;
const MAX_FAR_PERCENT: usize = 3;

/// Pixels whose largest channel difference exceeds [`CHANNEL_TOLERANCE`], and the largest one.
fn pixels_beyond_tolerance(image: &RgbaImage, reference: &RgbaImage) -> (usize, u8) {
    let mut far = 0usize;
    let mut worst = 0u8;
    for (a, b) in image.pixels().zip(reference.pixels()) {
        let d = a.0.iter().zip(b.0.iter()).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
        worst = worst.max(d);
        if d > CHANNEL_TOLERANCE {
            far += 1;
        }
    }
    (far, worst)
}

#[test]
fn gpu_errors_become_typed_errors_not_panics() {
    // Cause: wgpu's default reaction to an error outside an error scope is a panic, so a bad
    // upload or an exhausted device aborted `furbake preview` instead of exiting 1.
    let g = HeadlessGpu::new().expect("a wgpu adapter (lavapipe without a GPU)");
    assert!(g.check().is_ok(), "a fresh device has no failure");
    let buffer = g.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("sixteen bytes"),
        size: 16,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::UNIFORM,
        mapped_at_creation: false,
    });
    // A write past the end: a validation error outside any error scope.
    g.queue.write_buffer(&buffer, 64, &[0u8; 16]);
    match g.check() {
        Err(furbake_render::RenderError::Gpu { what }) => assert!(what.contains("outside any error scope"), "{what}"),
        other => panic!("expected a recorded GPU error, got {other:?}"),
    }
    assert!(g.check().is_ok(), "each failure is reported once");
    // The device still works afterwards.
    let target = RenderTarget::new(&g.device, 8, 8).unwrap();
    assert_eq!(read_back(&g.device, &g.queue, &target).unwrap().dimensions(), (8, 8));
}
