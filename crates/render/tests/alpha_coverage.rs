//! Alpha to coverage (`RenderSettings::alpha_to_coverage`; `coverage_alpha` in
//! `shaders/fur_common.wgsl`) on whatever adapter the machine has (lavapipe without a GPU; never
//! skips): a furry sphere drawn with the alpha test into a 4× multisampled target and resolved.
//! (a) With alpha to coverage the hairs' edges inside the shells are antialiased: the resolved
//!     frame's total variation (the sum of neighbouring pixels' differences, what aliasing
//!     raises) is lower than with the per-pixel alpha test, and the frames differ.
//! (b) On a single-sampled target the switch changes nothing (bit-identical frames).

use crate::common;

use std::sync::OnceLock;

use crate::common::gpu;
use furbake_render::headless::{read_back_texture, render_image};
use furbake_render::{FurAsset, FurRenderer, RenderSettings, ShellBlend, TargetDesc, View};
use furbake_runtime::{Camera, Light};
use image::RgbaImage;

const SIZE: u32 = 96;
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

fn sphere() -> &'static FurAsset {
    static SPHERE: OnceLock<FurAsset> = OnceLock::new();
    SPHERE.get_or_init(|| common::furry_sphere(16, 24, 16, 64, 0.15))
}

fn view() -> View {
    View {
        camera: Camera { eye: [0.0, 0.6, 2.6], target: [0.0; 3], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 },
        lighting: Light::default().into(),
        bounds_center: [0.0; 3],
        bounds_radius: 1.15,
    }
}

fn settings(alpha_to_coverage: bool) -> RenderSettings {
    RenderSettings { blend: ShellBlend::AlphaTest, alpha_threshold: 0.4, alpha_to_coverage, ..Default::default() }
}

/// One frame into a 4× multisampled colour + depth target, resolved and read back.
fn render_msaa(alpha_to_coverage: bool) -> RgbaImage {
    let g = gpu();
    let target = TargetDesc::new(FORMAT).with_depth(DEPTH, wgpu::CompareFunction::LessEqual).with_samples(4);
    let fur = FurRenderer::new(g.pipelines(), &g.queue, sphere(), &settings(alpha_to_coverage), &target).unwrap();
    let texture = |format, samples, usage| {
        g.device.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d { width: SIZE, height: SIZE, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let attachment = wgpu::TextureUsages::RENDER_ATTACHMENT;
    let color = texture(FORMAT, 4, attachment);
    let depth = texture(DEPTH, 4, attachment);
    let resolved = texture(FORMAT, 1, attachment | wgpu::TextureUsages::COPY_SRC);
    let (color, depth, resolve) = (
        color.create_view(&Default::default()),
        depth.create_view(&Default::default()),
        resolved.create_view(&Default::default()),
    );
    let mut encoder = g.device.create_command_encoder(&Default::default());
    fur.prepare(&g.queue, &mut encoder, &view().uniforms(SIZE, SIZE));
    {
        let clear = wgpu::Color { r: 0.0, g: 0.0, b: 0.0, a: 1.0 };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color,
                depth_slice: None,
                resolve_target: Some(&resolve),
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Discard },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        fur.render(&mut pass);
    }
    g.queue.submit([encoder.finish()]);
    g.check().unwrap();
    read_back_texture(&g.device, &g.queue, &resolved).unwrap()
}

/// Sum over the image of |p(x+1, y) − p(x, y)| + |p(x, y+1) − p(x, y)|, all channels.
fn total_variation(image: &RgbaImage) -> u64 {
    let mut sum = 0u64;
    for y in 0..SIZE - 1 {
        for x in 0..SIZE - 1 {
            let p = image.get_pixel(x, y);
            for q in [image.get_pixel(x + 1, y), image.get_pixel(x, y + 1)] {
                sum += (0..3).map(|c| p[c].abs_diff(q[c]) as u64).sum::<u64>();
            }
        }
    }
    sum
}

#[test]
fn alpha_to_coverage_antialiases_the_alpha_tested_hair() {
    let (on, off) = (render_msaa(true), render_msaa(false));
    let changed = on.pixels().zip(off.pixels()).filter(|(a, b)| a != b).count();
    let (tv_on, tv_off) = (total_variation(&on), total_variation(&off));
    println!("{changed} pixels changed; total variation {tv_on} with alpha to coverage, {tv_off} without");
    assert!(changed > (SIZE * SIZE / 20) as usize, "alpha to coverage changes the hair: only {changed} pixels");
    assert!(
        (tv_on as f64) < 0.9 * tv_off as f64,
        "alpha to coverage smooths the hair: total variation {tv_on} against {tv_off} without"
    );
}

#[test]
fn alpha_to_coverage_changes_nothing_on_a_single_sampled_target() {
    let g = gpu();
    let frame = |on| render_image(g, sphere(), &settings(on), &view(), SIZE, SIZE).unwrap();
    assert_eq!(frame(true).as_raw(), frame(false).as_raw());
}
