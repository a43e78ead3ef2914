//! furbake inside a host renderer: the example host (`examples/host.rs`, included here so the tests
//! run exactly the code users read) owns an MSAA HDR colour target and a depth buffer, draws its
//! own ground plane and box, and furbake's Fox and grass in the same pass. Checked on whatever
//! adapter the machine has (lavapipe without a GPU; never skipped):
//! - the box, placed between the camera and the Fox, occludes the fur — and the check has teeth:
//!   the same frame with fur that ignores the host's depth (compare `Always`) fails it;
//! - fur and grass validate and render into `Bgra8UnormSrgb` and `Rgba16Float`, 1× and 4×
//!   samples, and into a pass with a second colour attachment; unsupported targets are typed
//!   errors; renderers of one description share pipelines; resizing rebuilds nothing;
//! - a host frame of `prepare` + `render` neither submits nor waits inside furbake (the crate's
//!   blocking-call counter does not move, and the host's one submission is the next index);
//! - the host's tonemapped image matches the headless preview of the same objects where they
//!   overlap (no host geometry, same background), within a stated tolerance.

#[path = "../examples/host.rs"]
mod example;

use std::sync::OnceLock;

use crate::common::gpu;
use example::{Furbake, HostOptions, Packs, Placement, render_image};
use furbake_render::SceneFrame;
use furbake_render::headless::{HeadlessGpu, RenderTarget, read_back};
use furbake_render::testing::blocking_calls_on_this_thread;
use furbake_render::{FurAsset, FurRenderer, PipelineCache, RenderError, RenderSettings, ShellBlend, TargetDesc};
use image::RgbaImage;

const W: u32 = 200;
const H: u32 = 150;

/// The Fox with 16 shell layers and the grass patch at 60 blades/m², baked once.
fn packs() -> &'static Packs {
    static PACKS: OnceLock<Packs> = OnceLock::new();
    PACKS.get_or_init(|| example::bake_packs(16, 60.0).unwrap())
}

fn options(format: wgpu::TextureFormat, samples: u32) -> HostOptions {
    HostOptions { width: W, height: H, format, samples, ..HostOptions::default() }
}

fn furbake(target: &TargetDesc) -> Furbake {
    Furbake::new(gpu().pipelines(), &gpu().queue, packs(), target).unwrap()
}

/// Renderers with their own pipeline cache (tests that count pipelines; the shared cache grows
/// while other tests run in parallel).
fn furbake_in(pipelines: &PipelineCache, target: &TargetDesc) -> Furbake {
    Furbake::new(pipelines, &gpu().queue, packs(), target).unwrap()
}

fn save(image: &RgbaImage, name: &str) {
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    image.save(dir.join(name)).unwrap();
}

fn is_box_blue(p: &image::Rgba<u8>) -> bool {
    p[2] as i32 > p[0] as i32 + 60 && p[2] as i32 > p[1] as i32 + 40
}

fn max_channel_diff(a: &image::Rgba<u8>, b: &image::Rgba<u8>) -> u8 {
    a.0.iter().zip(b.0.iter()).map(|(x, y)| x.abs_diff(*y)).max().unwrap()
}

/// Pixels of the box with all eight neighbours also box (away from its MSAA-blended edges).
fn box_interior(image: &RgbaImage) -> Vec<(u32, u32)> {
    let (w, h) = image.dimensions();
    let mut out = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let all = (0..9).all(|k| is_box_blue(image.get_pixel(x + k % 3 - 1, y + k / 3 - 1)));
            if all {
                out.push((x, y));
            }
        }
    }
    out
}

#[test]
fn a_box_in_front_of_the_fox_occludes_the_fur() {
    let g = gpu();
    let base = options(wgpu::TextureFormat::Rgba16Float, 4);
    let fur = furbake(&base.target_desc());
    let placement = Placement::new(&fur);
    let render = |furbake: Option<&Furbake>, with_box: bool| {
        render_image(g, furbake, &placement, &HostOptions { r#box: with_box, ..base.clone() }).unwrap()
    };
    let host_only = render(None, true);
    let host_bare = render(None, false);
    let with_fur = render(Some(&fur), true);
    let fur_no_box = render(Some(&fur), false);
    g.check().unwrap();
    for (image, name) in [(&host_only, "host_only"), (&with_fur, "host_box_fur"), (&fur_no_box, "host_fur")] {
        save(image, &format!("{name}.png"));
    }
    let interior = box_interior(&host_only);
    assert!(interior.len() > 300, "the box covers only {} interior pixels", interior.len());
    // The box really stands in front of the Fox: without it, most of its pixels show fur.
    let fur_behind = interior.iter().filter(|&&(x, y)| fur_no_box.get_pixel(x, y) != host_bare.get_pixel(x, y)).count();
    assert!(fur_behind * 2 > interior.len(), "only {fur_behind} of {} box pixels hide fur", interior.len());
    // With fur drawn after the box in the same pass, every box pixel still shows the box.
    let changed: Vec<_> = interior
        .iter()
        .filter(|&&(x, y)| max_channel_diff(with_fur.get_pixel(x, y), host_only.get_pixel(x, y)) > 1)
        .collect();
    println!(
        "box: {} interior pixels, {fur_behind} hide fur, {} changed by the fur pass",
        interior.len(),
        changed.len()
    );
    assert!(changed.is_empty(), "{} box pixels show fur, e.g. {:?}", changed.len(), &changed[..changed.len().min(5)]);

    // The check has teeth: fur that ignores the host's depth (compare Always) paints over the box.
    let mut always = base.target_desc();
    always.depth.as_mut().unwrap().compare = wgpu::CompareFunction::Always;
    let careless = furbake(&always);
    let over = render(Some(&careless), true);
    save(&over, "host_box_fur_always.png");
    let painted = interior
        .iter()
        .filter(|&&(x, y)| max_channel_diff(over.get_pixel(x, y), host_only.get_pixel(x, y)) > 1)
        .count();
    assert!(painted * 4 > interior.len(), "fur drawn with compare Always changed only {painted} box pixels");
}

/// Pixels that differ from the host-only frame (fur or grass drawn there) and, of those, green.
fn drawn_pixels(image: &RgbaImage, host_only: &RgbaImage) -> (usize, usize) {
    let mut drawn = 0;
    let mut green = 0;
    for (a, b) in image.pixels().zip(host_only.pixels()) {
        if max_channel_diff(a, b) > 8 {
            drawn += 1;
            green += (a[1] as i32 > a[0] as i32 + 10 && a[1] as i32 > a[2] as i32 + 10) as usize;
        }
    }
    (drawn, green)
}

#[test]
fn fur_and_grass_render_into_ldr_and_hdr_targets_with_and_without_msaa() {
    let g = gpu();
    let cases = [
        (wgpu::TextureFormat::Bgra8UnormSrgb, 1),
        (wgpu::TextureFormat::Bgra8UnormSrgb, 4),
        (wgpu::TextureFormat::Rgba16Float, 1),
        (wgpu::TextureFormat::Rgba16Float, 4),
    ];
    let mut checked = 0;
    let pipelines = PipelineCache::new(&g.device);
    for (format, samples) in cases {
        let options = options(format, samples);
        let before = pipelines.render_pipeline_count();
        let fur = furbake_in(&pipelines, &options.target_desc());
        let created = pipelines.render_pipeline_count() - before;
        // Skin, shell back faces, shell front faces, fin and silhouette fin for the Fox (skinned)
        // and for the patch (static), and the blades.
        assert_eq!(created, 11, "{format:?} × {samples}: pipelines created");
        // A second set of renderers for the same pass reuses every pipeline.
        let again = furbake_in(&pipelines, &options.target_desc());
        assert_eq!(pipelines.render_pipeline_count() - before, created, "{format:?}×{samples}: rebuilt");
        let placement = Placement::new(&fur);
        let host_only = render_image(g, None, &placement, &options).unwrap();
        let image = render_image(g, Some(&fur), &placement, &options).unwrap();
        let image_again = render_image(g, Some(&again), &placement, &options).unwrap();
        g.check().unwrap_or_else(|e| panic!("{format:?} × {samples}: {e}"));
        save(&image, &format!("host_{format:?}_{samples}x.png"));
        let (drawn, green) = drawn_pixels(&image, &host_only);
        println!("{format:?} × {samples}: {created} pipelines, {drawn} pixels drawn by furbake, {green} green");
        assert!(drawn > (W * H / 10) as usize, "{format:?} × {samples}: only {drawn} pixels drawn");
        assert!(green > 200, "{format:?} × {samples}: only {green} grass pixels");
        assert_eq!(image, image_again, "{format:?} × {samples}: renderers sharing pipelines draw alike");
        checked += 1;
    }
    assert_eq!(checked, cases.len());
}

#[test]
fn a_pass_with_a_second_colour_attachment_keeps_it_untouched() {
    // A G-buffer-like host pass: attachment 1 (Rgba8Unorm) is listed in the target description
    // and left unwritten by the fur (write mask empty), so it keeps its clear colour.
    let g = gpu();
    let mut desc = TargetDesc::new(wgpu::TextureFormat::Rgba16Float)
        .with_depth(example::HOST_DEPTH_FORMAT, wgpu::CompareFunction::LessEqual);
    desc.extra_color_formats.push(wgpu::TextureFormat::Rgba8Unorm);
    let asset = FurAsset::from_pack(&packs().fox, true).unwrap();
    let fox = FurRenderer::new(g.pipelines(), &g.queue, &asset, &RenderSettings::default(), &desc).unwrap();
    let texture = |format, usage| {
        g.device.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d { width: 64, height: 64, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | usage,
            view_formats: &[],
        })
    };
    let hdr = texture(wgpu::TextureFormat::Rgba16Float, wgpu::TextureUsages::empty());
    let extra = texture(wgpu::TextureFormat::Rgba8Unorm, wgpu::TextureUsages::COPY_SRC);
    let depth = texture(example::HOST_DEPTH_FORMAT, wgpu::TextureUsages::empty());
    let (hdr_view, extra_view, depth_view) = (
        hdr.create_view(&Default::default()),
        extra.create_view(&Default::default()),
        depth.create_view(&Default::default()),
    );
    let (_, radius) = asset.bounding_sphere();
    let view = furbake_render::View::framing(asset.bounding_sphere().0, radius);
    let mut encoder = g.device.create_command_encoder(&Default::default());
    fox.prepare(&g.queue, &mut encoder, &view.uniforms(64, 64));
    {
        let attachment = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::RED), store: wgpu::StoreOp::Store },
            })
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("two colour attachments"),
            color_attachments: &[attachment(&hdr_view), attachment(&extra_view)],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        fox.render(&mut pass);
    }
    g.queue.submit([encoder.finish()]);
    let second = furbake_render::headless::read_back_texture(&g.device, &g.queue, &extra).unwrap();
    g.check().unwrap();
    let red = second.pixels().filter(|p| p.0 == [255, 0, 0, 255]).count();
    assert_eq!(red, 64 * 64, "attachment 1 was written");
}

#[test]
fn unsupported_targets_are_typed_errors() {
    let g = gpu();
    let asset = FurAsset::from_pack(&packs().fox, true).unwrap();
    let blended = RenderSettings::default();
    let tested = RenderSettings { blend: ShellBlend::AlphaTest, alpha_threshold: 0.4, ..Default::default() };
    let depth = |d: TargetDesc| d.with_depth(wgpu::TextureFormat::Depth32Float, wgpu::CompareFunction::LessEqual);
    let cases = [
        ("3 samples", depth(TargetDesc::new(wgpu::TextureFormat::Rgba8UnormSrgb)).with_samples(3), blended),
        ("unblendable Rgba32Float", depth(TargetDesc::new(wgpu::TextureFormat::Rgba32Float)), blended),
        ("Rgba32Float 4×", depth(TargetDesc::new(wgpu::TextureFormat::Rgba32Float)).with_samples(4), tested),
        ("a depth format as colour", depth(TargetDesc::new(wgpu::TextureFormat::Depth32Float)), blended),
        (
            "a colour format as depth",
            TargetDesc::new(wgpu::TextureFormat::Rgba8Unorm)
                .with_depth(wgpu::TextureFormat::Rgba8Unorm, wgpu::CompareFunction::Less),
            blended,
        ),
    ];
    let mut refused = 0;
    for (what, desc, settings) in &cases {
        match FurRenderer::new(g.pipelines(), &g.queue, &asset, settings, desc) {
            Err(RenderError::UnsupportedTarget { what: message }) => println!("{what}: {message}"),
            Err(e) => panic!("{what}: expected UnsupportedTarget, got {e}"),
            Ok(_) => panic!("{what}: accepted"),
        }
        refused += 1;
    }
    assert_eq!(refused, cases.len());
    // Alpha-tested shells need no blending: the same unblendable format is accepted.
    let plain = depth(TargetDesc::new(wgpu::TextureFormat::Rgba32Float));
    FurRenderer::new(g.pipelines(), &g.queue, &asset, &tested, &plain).unwrap();
    g.check().unwrap();
}

#[test]
fn resizing_the_host_target_rebuilds_no_renderer() {
    let g = gpu();
    let cache = PipelineCache::new(&g.device);
    let fur = furbake_in(&cache, &options(wgpu::TextureFormat::Rgba16Float, 4).target_desc());
    let placement = Placement::new(&fur);
    let pipelines = cache.render_pipeline_count();
    let mut drawn = Vec::new();
    for (width, height) in [(W, H), (W / 2 + 13, H / 2 + 7), (W * 3 / 2, H)] {
        let options = HostOptions { width, height, ..options(wgpu::TextureFormat::Rgba16Float, 4) };
        let host_only = render_image(g, None, &placement, &options).unwrap();
        let image = render_image(g, Some(&fur), &placement, &options).unwrap();
        assert_eq!(image.dimensions(), (width, height));
        drawn.push(drawn_pixels(&image, &host_only).0);
    }
    g.check().unwrap();
    assert_eq!(cache.render_pipeline_count(), pipelines, "a resize created pipelines");
    assert!(drawn.iter().all(|&n| n > 500), "furbake pixels per size: {drawn:?}");
}

/// The index of a submission, from its `Debug` form (`SubmissionIndex { index: N }`; wgpu keeps the
/// number private).
fn submission_number(index: wgpu::SubmissionIndex) -> u64 {
    let text = format!("{index:?}");
    let digits: String = text.chars().filter(char::is_ascii_digit).collect();
    digits.parse().unwrap_or_else(|_| panic!("no number in {text}"))
}

#[test]
fn a_host_frame_neither_submits_nor_waits_inside_furbake() {
    // A device of its own: no other test submits on its queue, so the host's submission indices
    // are consecutive unless furbake submits.
    let g = HeadlessGpu::new().unwrap();
    let options = options(wgpu::TextureFormat::Rgba16Float, 4);
    let fur = Furbake::new(g.pipelines(), &g.queue, packs(), &options.target_desc()).unwrap();
    let placement = Placement::new(&fur);
    let host = example::Host::new(&g.device, &options, &placement);
    let mut frames = 0;
    for _ in 0..3 {
        let calls = blocking_calls_on_this_thread();
        let start = submission_number(g.queue.submit([]));
        let mut encoder = g.device.create_command_encoder(&Default::default());
        // The Fox is skinned, so its prepare records a compute dispatch into the host's encoder.
        host.encode_frame(&g.queue, &mut encoder, &placement, Some(&fur));
        assert_eq!(blocking_calls_on_this_thread(), calls, "furbake submitted or waited during the frame");
        let end = submission_number(g.queue.submit([encoder.finish()]));
        assert_eq!(end, start + 1, "a submission happened between the host's two");
        frames += 1;
    }
    assert!(fur.fox.skinning().is_some(), "the Fox frame exercised the skinning dispatch");
    // Both checks have teeth: a furbake call that submits (the blade pose readback's compute)
    // moves the counter and the index.
    let (calls, start) = (blocking_calls_on_this_thread(), submission_number(g.queue.submit([])));
    fur.blades.compute(&g.device, &g.queue).unwrap();
    assert_eq!(blocking_calls_on_this_thread(), calls + 1);
    assert_eq!(submission_number(g.queue.submit([])), start + 2);
    // The counter counts: the headless readback submits and waits.
    let calls = blocking_calls_on_this_thread();
    furbake_render::headless::read_back_texture(&g.device, &g.queue, host.output()).unwrap();
    assert!(blocking_calls_on_this_thread() >= calls + 2);
    g.check().unwrap();
    assert_eq!(frames, 3);
}

// Tolerance of the host-versus-headless comparison: the two paths run the same shaders on the
// same geometry from the same view, but the host blends into a 16-bit float target and the
// headless host into an 8-bit sRGB one, where each of the 16 blended shell layers re-rounds the
// colour to 8 bits (the errors add up most in the dark, tinted grass), and the host's tonemap
// compresses linear values above 0.8 (lit highlights): at 1× a channel may differ by up to
// 16/255, and at most 1 % of the drawn pixels by more (measured on lavapipe: worst 15/255). With
// 4× MSAA the thin grass blades and hair tips cover a fraction of a pixel, which MSAA averages and a
// single sample takes all-or-nothing (a 1× frame shows a third of a blade's length as whole
// pixels, MSAA all of it at a third of the colour), so the frames are compared as means of
// 8×8-pixel squares averaged in linear light (what an MSAA resolve averages; both estimate the
// same coverage, and 8×8 holds enough blade pixels for the 1× estimate to settle): a square's
// channel mean may differ by up to 24/255, at most 2 % of the drawn squares by more (measured:
// worst 12/255 at 8×8, 21/255 with an untinted white patch; 49/255 at 4×4, where a square holds
// too few blade pixels). A broken
// frame — checked below with the Fox missing — changes far more.
const CHANNEL_TOLERANCE: u8 = 16;
const BLOCK: u32 = 8;
const BLOCK_TOLERANCE: f64 = 24.0;

/// The sRGB encoding of a linear value in [0, 1], on the 0–255 scale (sRGB IEC 61966-2-1).
fn encode_srgb(linear: f64) -> f64 {
    let c = if linear <= 0.003_130_8 { linear * 12.92 } else { 1.055 * linear.powf(1.0 / 2.4) - 0.055 };
    c * 255.0
}

/// Per-channel means of the `block × block` squares of `image` (whole squares only), averaged in
/// linear light — what an MSAA resolve averages — and encoded back to sRGB (alpha as stored).
fn block_means(image: &RgbaImage, block: u32) -> Vec<[f64; 4]> {
    let decode = |c: u8| {
        let c = c as f64 / 255.0;
        if c <= 0.040_45 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    };
    let (w, h) = (image.width() / block, image.height() / block);
    let n = (block * block) as f64;
    let mut out = vec![[0.0; 4]; (w * h) as usize];
    for (x, y, p) in image.enumerate_pixels().filter(|(x, y, _)| x / block < w && y / block < h) {
        let cell = &mut out[((y / block) * w + x / block) as usize];
        for c in 0..3 {
            cell[c] += decode(p[c]) / n;
        }
        cell[3] += p[3] as f64 / n;
    }
    for cell in &mut out {
        for c in &mut cell[..3] {
            *c = encode_srgb(*c);
        }
    }
    out
}

/// Compares `image` with `reference` in `block`-pixel squares (1: per pixel): the squares where
/// either differs from the background `bg`, how many of those differ by more than `tolerance` in
/// some channel mean, and the largest difference.
fn compare(image: &RgbaImage, reference: &RgbaImage, bg: [u8; 4], block: u32, tolerance: f64) -> (usize, usize, f64) {
    let (a, b) = (block_means(image, block), block_means(reference, block));
    // A square of background pixels, averaged the same way (equal bits when untouched).
    let bg = block_means(&RgbaImage::from_pixel(block, block, image::Rgba(bg)), block)[0];
    let (mut drawn, mut far, mut worst) = (0, 0, 0.0f64);
    for (x, y) in a.iter().zip(&b) {
        if *x == bg && *y == bg {
            continue;
        }
        drawn += 1;
        let d = (0..4).map(|c| (x[c] - y[c]).abs()).fold(0.0, f64::max);
        worst = worst.max(d);
        far += (d > tolerance) as usize;
    }
    (drawn, far, worst)
}

#[test]
fn the_host_matches_the_headless_preview_where_they_overlap() {
    let g = gpu();
    let background = RenderSettings::default().background;
    // The headless host: the same objects built for its RenderTarget, drawn by SceneFrame.
    let headless = furbake(&RenderTarget::desc());
    let target = RenderTarget::new(&g.device, W, H).unwrap();
    let placement = Placement::new(&headless);
    let frame = SceneFrame { camera: Some(placement.view.camera), lighting: placement.view.lighting, background };
    let view = frame.render(&g.device, &g.queue, &target, &headless.objects(&placement)).unwrap();
    let reference = read_back(&g.device, &g.queue, &target).unwrap();
    save(&reference, "host_reference_headless.png");
    let bg = reference.get_pixel(0, 0).0;
    let mut compared = 0;
    for (samples, block, tolerance, max_far_percent) in
        [(1u32, 1u32, CHANNEL_TOLERANCE as f64, 1usize), (4, BLOCK, BLOCK_TOLERANCE, 2)]
    {
        let options = HostOptions {
            ground: false,
            r#box: false,
            clear: background,
            ..options(wgpu::TextureFormat::Rgba16Float, samples)
        };
        let fur = furbake(&options.target_desc());
        let placement = Placement::new(&fur);
        assert_eq!(placement.view, view, "the host and the headless preview frame the objects alike");
        let image = render_image(g, Some(&fur), &placement, &options).unwrap();
        save(&image, &format!("host_vs_headless_{samples}x.png"));
        let (drawn, far, worst) = compare(&image, &reference, bg, block, tolerance);
        println!(
            "{samples}×, {block}² squares: {drawn} drawn, {far} differ by more than {tolerance}/255, worst {worst:.1}"
        );
        assert!(drawn * (block * block) as usize > (W * H / 10) as usize, "{samples}×: only {drawn} drawn squares");
        assert!(
            far * 100 <= drawn * max_far_percent,
            "{samples}×: {far} of {drawn} {block}² squares differ by more than {tolerance}/255 (worst {worst:.1})"
        );
        compared += 1;
    }
    // The tolerance catches a wrong frame: the same host frame without the Fox fails it.
    let options =
        HostOptions { ground: false, r#box: false, clear: background, ..options(wgpu::TextureFormat::Rgba16Float, 4) };
    let fur = furbake(&options.target_desc());
    let placement = Placement::new(&fur);
    let host = example::Host::new(&g.device, &options, &placement);
    let mut encoder = g.device.create_command_encoder(&Default::default());
    // The Fox's slot holds a second grass patch renderer, drawn at the Fox's placement (1 % scale).
    let patch = FurAsset::from_pack(&packs().grass, true).unwrap();
    let settings = RenderSettings::default();
    let stand_in = FurRenderer::new(g.pipelines(), &g.queue, &patch, &settings, &options.target_desc()).unwrap();
    let partial = Furbake { fox: stand_in, ..fur };
    host.encode_frame(&g.queue, &mut encoder, &placement, Some(&partial));
    g.queue.submit([encoder.finish()]);
    let without_fox = furbake_render::headless::read_back_texture(&g.device, &g.queue, host.output()).unwrap();
    let (drawn, far, _) = compare(&without_fox, &reference, bg, BLOCK, BLOCK_TOLERANCE);
    println!("without the Fox: {far} of {drawn} {BLOCK}² squares beyond tolerance");
    assert!(far * 100 > drawn * 2 * 5, "a frame without the Fox passes as the reference ({far} of {drawn})");
    g.check().unwrap();
    assert_eq!(compared, 2);
}
