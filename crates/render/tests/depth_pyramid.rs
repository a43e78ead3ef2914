//! The hierarchical depth pyramid (`DepthPyramid`, `shaders/depth_pyramid.wgsl`) built on the GPU
//! from a host's depth texture: level 0 is the depth as the GPU reads it, and every further level
//! equals the CPU reduction (`furbake_render::testing::reduce_level`) of the level below —
//! farthest depth over the covered texels, odd edges included — bit for bit, for ordinary and
//! reversed depth and odd sizes. Runs on whatever adapter the machine has (lavapipe without a
//! GPU) and never skips.

use crate::common::gpu;
use furbake_render::DepthPyramid;
use furbake_render::testing::reduce_level;

/// A `Depth16Unorm` texture of `w` × `h` filled with pseudo-random depths (a hash of the texel).
fn depth_texture(w: u32, h: u32, seed: u32) -> wgpu::Texture {
    let g = gpu();
    let texture = g.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("test depth"),
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Depth16Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let texels: Vec<u16> = (0..w * h)
        .map(|i| {
            let mut x = i.wrapping_mul(0x9E37_79B9) ^ seed;
            x ^= x >> 15;
            x = x.wrapping_mul(0x85EB_CA6B);
            (x >> 16) as u16
        })
        .collect();
    g.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::DepthOnly,
        },
        bytemuck::cast_slice(&texels),
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w * 2), rows_per_image: Some(h) },
        wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
    );
    texture
}

fn check(w: u32, h: u32, reversed: bool) {
    let g = gpu();
    let depth = depth_texture(w, h, w * 31 + h);
    let pyramid = DepthPyramid::new(&g.device, w, h, reversed).unwrap();
    let mut encoder = g.device.create_command_encoder(&Default::default());
    pyramid.record(&g.device, &mut encoder, &depth).unwrap();
    g.queue.submit([encoder.finish()]);
    let mut below = pyramid.read_level(&g.device, &g.queue, 0).unwrap();
    assert_eq!(below.len(), (w * h) as usize);
    // Level 0 is the depth buffer: 16-bit depths in [0, 1], not all equal.
    assert!(below.iter().all(|d| (0.0..=1.0).contains(d)));
    assert!(below.iter().any(|&d| d != below[0]));
    let (mut lw, mut lh) = (w, h);
    for level in 1..pyramid.levels() {
        let got = pyramid.read_level(&g.device, &g.queue, level).unwrap();
        let want = reduce_level(&below, lw, lh, reversed);
        assert_eq!(got, want, "{w}×{h} level {level} (reversed: {reversed})");
        (lw, lh, below) = ((lw / 2).max(1), (lh / 2).max(1), got);
    }
    assert_eq!((lw, lh), (1, 1));
    // The top is the farthest depth of the whole buffer.
    let all = pyramid.read_level(&g.device, &g.queue, 0).unwrap();
    let far = if reversed { all.iter().copied().fold(1.0, f32::min) } else { all.iter().copied().fold(0.0, f32::max) };
    assert_eq!(below, [far]);
}

#[test]
fn every_level_is_the_farthest_depth_of_the_level_below() {
    check(37, 23, false);
    check(64, 48, false);
    check(37, 23, true);
    check(1, 9, false);
}

#[test]
fn a_depth_texture_of_another_size_is_refused() {
    let g = gpu();
    let pyramid = DepthPyramid::new(&g.device, 16, 16, false).unwrap();
    let mut encoder = g.device.create_command_encoder(&Default::default());
    let e = pyramid.record(&g.device, &mut encoder, &depth_texture(8, 16, 1)).unwrap_err().to_string();
    assert!(e.contains("8×16") && e.contains("16×16"), "{e}");
    assert!(DepthPyramid::new(&g.device, 0, 4, false).is_err());
}

/// One pyramid fed by a host that swaps depth textures (double-buffered depth, a new texture
/// after a resize): each record reads the texture it is given, not the one it read before (the
/// copy pass's bind group is kept per texture).
#[test]
fn each_record_reads_the_texture_it_is_given() {
    let g = gpu();
    let (a, b) = (depth_texture(20, 12, 1), depth_texture(20, 12, 2));
    let pyramid = DepthPyramid::new(&g.device, 20, 12, false).unwrap();
    let level0 = |depth: &wgpu::Texture| {
        let mut encoder = g.device.create_command_encoder(&Default::default());
        pyramid.record(&g.device, &mut encoder, depth).unwrap();
        g.queue.submit([encoder.finish()]);
        pyramid.read_level(&g.device, &g.queue, 0).unwrap()
    };
    let (first_a, first_b, again_a) = (level0(&a), level0(&b), level0(&a));
    assert_ne!(first_a, first_b, "the two textures hold different depths");
    assert_eq!(first_a, again_a);
    assert_eq!(level0(&b), first_b);
}
