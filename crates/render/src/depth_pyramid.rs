//! The hierarchical depth (Hi-Z) pyramid of the host's depth buffer (`shaders/depth_pyramid.wgsl`):
//! the first half of occlusion culling for grass (Jahrmann & Wimmer 2017's fourth test), built on
//! the GPU from the depth the host passes through the middleware, one compute pass recorded into
//! the host's encoder. Level 0 is the depth itself (`R32Float`), each further level (the texture's
//! mip chain, floor halving) the farthest depth of the texels below it covers — the largest, or
//! the smallest for reversed depth — so a bound nearer than nothing in a texel's footprint is
//! hidden. Blade culling tests clusters and blades against it ([`crate::BladeRenderer::
//! set_occlusion`]; docs/design.md "Depth pyramid and occlusion culling").

use wgpu::util::DeviceExt;

use crate::RenderError;
use crate::shaders::DEPTH_PYRAMID_WGSL;

/// Bytes between levels' uniforms (a multiple of every adapter's uniform offset alignment).
const LEVEL_STRIDE: u64 = 256;

/// One level's uniforms (`PyramidLevel` in `depth_pyramid.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PyramidLevel {
    sizes: [u32; 4],
    flags: [u32; 4],
}

/// A depth pyramid for depth buffers of one size ([`DepthPyramid::new`]); rebuilt from the
/// host's depth each frame by [`DepthPyramid::record`].
pub struct DepthPyramid {
    texture: wgpu::Texture,
    size: (u32, u32),
    reversed: bool,
    uniforms: wgpu::Buffer,
    copy_layout: wgpu::BindGroupLayout,
    copy: wgpu::ComputePipeline,
    reduce: wgpu::ComputePipeline,
    /// `reduce_groups[i]` reads level `i` and writes level `i + 1`.
    reduce_groups: Vec<wgpu::BindGroup>,
    /// The copy pass's bind group for the last depth texture recorded from: a host that draws
    /// into the same depth texture every frame builds it once (a new texture, after a resize,
    /// replaces it; the old one is held until then).
    copy_group: std::sync::Mutex<Option<(wgpu::Texture, wgpu::BindGroup)>>,
}

impl std::fmt::Debug for DepthPyramid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DepthPyramid").field("size", &self.size).field("levels", &self.levels()).finish()
    }
}

/// The mip sizes of a `width` × `height` chain down to 1 × 1.
fn level_sizes(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut sizes = vec![(width, height)];
    while let Some(&(w, h)) = sizes.last().filter(|&&(w, h)| w > 1 || h > 1) {
        sizes.push(((w / 2).max(1), (h / 2).max(1)));
    }
    sizes
}

impl DepthPyramid {
    /// A pyramid for `width` × `height` depth buffers; `reversed_depth` when larger depths are
    /// nearer (the depth attachment compares with `GreaterEqual`). A zero size, or one above the
    /// device's 2D texture limit, is a [`RenderError::Parameter`].
    pub fn new(
        device: &wgpu::Device,
        width: u32,
        height: u32,
        reversed_depth: bool,
    ) -> Result<DepthPyramid, RenderError> {
        let max = device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::Parameter {
                what: format!("a depth pyramid of {width}×{height} (each side in 1..={max})"),
            });
        }
        let sizes = level_sizes(width, height);
        crate::gpu_scope(device, "creating a depth pyramid", || {
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("furbake depth pyramid"),
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: sizes.len() as u32,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::R32Float,
                usage: wgpu::TextureUsages::STORAGE_BINDING
                    | wgpu::TextureUsages::TEXTURE_BINDING
                    | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            });
            let mut levels = Vec::with_capacity(sizes.len() * LEVEL_STRIDE as usize);
            for (i, &(w, h)) in sizes.iter().enumerate() {
                // Level 0 copies the depth (input = output size); level i reduces level i − 1.
                let (iw, ih) = if i == 0 { (w, h) } else { sizes[i - 1] };
                let level = PyramidLevel { sizes: [iw, ih, w, h], flags: [reversed_depth as u32, 0, 0, 0] };
                levels.extend_from_slice(bytemuck::bytes_of(&level));
                levels.resize((i + 1) * LEVEL_STRIDE as usize, 0);
            }
            let uniforms = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("furbake depth pyramid levels"),
                contents: &levels,
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let compute = wgpu::ShaderStages::COMPUTE;
            let uniform = wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: compute,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: wgpu::BufferSize::new(size_of::<PyramidLevel>() as u64),
                },
                count: None,
            };
            let output = wgpu::BindGroupLayoutEntry {
                binding: 3,
                visibility: compute,
                ty: wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format: wgpu::TextureFormat::R32Float,
                    view_dimension: wgpu::TextureViewDimension::D2,
                },
                count: None,
            };
            let copy_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("furbake depth pyramid copy"),
                entries: &[
                    uniform,
                    wgpu::BindGroupLayoutEntry {
                        binding: 1,
                        visibility: compute,
                        ty: wgpu::BindingType::Texture {
                            sample_type: wgpu::TextureSampleType::Float { filterable: false },
                            view_dimension: wgpu::TextureViewDimension::D2,
                            multisampled: false,
                        },
                        count: None,
                    },
                    output,
                ],
            });
            let reduce_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("furbake depth pyramid reduce"),
                entries: &[
                    uniform,
                    wgpu::BindGroupLayoutEntry {
                        binding: 2,
                        visibility: compute,
                        ty: wgpu::BindingType::Texture {
                            sample_type: wgpu::TextureSampleType::Float { filterable: false },
                            view_dimension: wgpu::TextureViewDimension::D2,
                            multisampled: false,
                        },
                        count: None,
                    },
                    output,
                ],
            });
            let level_view = |i: usize| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    base_mip_level: i as u32,
                    mip_level_count: Some(1),
                    ..Default::default()
                })
            };
            let level_binding = || {
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &uniforms,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<PyramidLevel>() as u64),
                })
            };
            let reduce_groups = (1..sizes.len())
                .map(|i| {
                    device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("furbake depth pyramid reduce"),
                        layout: &reduce_layout,
                        entries: &[
                            wgpu::BindGroupEntry { binding: 0, resource: level_binding() },
                            wgpu::BindGroupEntry {
                                binding: 2,
                                resource: wgpu::BindingResource::TextureView(&level_view(i - 1)),
                            },
                            wgpu::BindGroupEntry {
                                binding: 3,
                                resource: wgpu::BindingResource::TextureView(&level_view(i)),
                            },
                        ],
                    })
                })
                .collect();
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("furbake depth_pyramid.wgsl"),
                source: wgpu::ShaderSource::Wgsl(DEPTH_PYRAMID_WGSL.into()),
            });
            let pipeline = |entry: &str, layout: &wgpu::BindGroupLayout| {
                let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(entry),
                    bind_group_layouts: &[Some(layout)],
                    immediate_size: 0,
                });
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            Ok(DepthPyramid {
                copy: pipeline("cs_depth_copy", &copy_layout),
                reduce: pipeline("cs_depth_reduce", &reduce_layout),
                texture,
                size: (width, height),
                reversed: reversed_depth,
                uniforms,
                copy_layout,
                reduce_groups,
                copy_group: std::sync::Mutex::new(None),
            })
        })
    }

    /// Levels, 1 × 1 included.
    pub fn levels(&self) -> u32 {
        self.texture.mip_level_count()
    }

    /// The depth size it is built for.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// True when larger depths are nearer.
    pub fn reversed_depth(&self) -> bool {
        self.reversed
    }

    /// The pyramid (`R32Float`, one mip per level), for a culling pass to read.
    pub fn texture(&self) -> &wgpu::Texture {
        &self.texture
    }

    /// Records the pyramid of `depth` (a single-sampled texture of a depth format, of this
    /// pyramid's size, with `TEXTURE_BINDING`) into `encoder`, after the host's pass that wrote the
    /// depth. Never submits or waits. A depth texture of another size, format or sample count
    /// is a [`RenderError::Parameter`] and records nothing.
    pub fn record(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        depth: &wgpu::Texture,
    ) -> Result<(), RenderError> {
        if (depth.width(), depth.height()) != self.size
            || !depth.format().has_depth_aspect()
            || depth.sample_count() != 1
            || !depth.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING)
        {
            return Err(RenderError::Parameter {
                what: format!(
                    "a depth pyramid of {}×{} built from a {}×{} {:?} texture with {} samples and usage {:?} \
                     (a single-sampled depth texture of the pyramid's size with TEXTURE_BINDING)",
                    self.size.0,
                    self.size.1,
                    depth.width(),
                    depth.height(),
                    depth.format(),
                    depth.sample_count(),
                    depth.usage()
                ),
            });
        }
        let mut cached = self.copy_group.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if cached.as_ref().is_none_or(|(texture, _)| texture != depth) {
            *cached = Some((depth.clone(), self.copy_group_for(device, depth)));
        }
        let copy_group = &cached.as_ref().expect("set above").1;
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("furbake depth pyramid"),
            timestamp_writes: None,
        });
        let groups = |w: u32, h: u32| (w.div_ceil(8), h.div_ceil(8));
        pass.set_pipeline(&self.copy);
        pass.set_bind_group(0, copy_group, &[0]);
        let (gx, gy) = groups(self.size.0, self.size.1);
        pass.dispatch_workgroups(gx, gy, 1);
        pass.set_pipeline(&self.reduce);
        for (i, group) in self.reduce_groups.iter().enumerate() {
            let level = i as u32 + 1;
            let (w, h) = ((self.size.0 >> level).max(1), (self.size.1 >> level).max(1));
            pass.set_bind_group(0, group, &[(level as u64 * LEVEL_STRIDE) as u32]);
            let (gx, gy) = groups(w, h);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        Ok(())
    }

    /// The copy pass's bind group reading `depth` and writing level 0.
    fn copy_group_for(&self, device: &wgpu::Device, depth: &wgpu::Texture) -> wgpu::BindGroup {
        let depth_view = depth.create_view(&wgpu::TextureViewDescriptor {
            aspect: wgpu::TextureAspect::DepthOnly,
            mip_level_count: Some(1),
            ..Default::default()
        });
        let level0 = self.texture.create_view(&wgpu::TextureViewDescriptor {
            base_mip_level: 0,
            mip_level_count: Some(1),
            ..Default::default()
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake depth pyramid copy"),
            layout: &self.copy_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &self.uniforms,
                        offset: 0,
                        size: wgpu::BufferSize::new(size_of::<PyramidLevel>() as u64),
                    }),
                },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&depth_view) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&level0) },
            ],
        })
    }
}

/// The CPU twin of one reduction (`cs_depth_reduce`): level `i + 1` (`(w / 2).max(1)` ×
/// `(h / 2).max(1)`) of a `w` × `h` level, each texel the farthest of the input texels it covers.
#[cfg(feature = "testing")]
pub fn reduce_level(input: &[f32], w: u32, h: u32, reversed_depth: bool) -> Vec<f32> {
    let (ow, oh) = ((w / 2).max(1), (h / 2).max(1));
    let farther = |a: f32, b: f32| if reversed_depth { a.min(b) } else { a.max(b) };
    let mut out = Vec::with_capacity((ow * oh) as usize);
    for y in 0..oh {
        for x in 0..ow {
            let x1 = if x + 1 == ow { w } else { 2 * x + 2 };
            let y1 = if y + 1 == oh { h } else { 2 * y + 2 };
            let mut d = input[(2 * y * w + 2 * x).min(w * h - 1) as usize];
            for yy in (2 * y).min(h - 1)..y1.max(2 * y + 1).min(h) {
                for xx in (2 * x).min(w - 1)..x1.max(2 * x + 1).min(w) {
                    d = farther(d, input[(yy * w + xx) as usize]);
                }
            }
            out.push(d);
        }
    }
    out
}

#[cfg(feature = "testing")]
impl DepthPyramid {
    /// Reads level `level` back (row-major, `size >> level` clamped to 1); submits and waits.
    pub fn read_level(&self, device: &wgpu::Device, queue: &wgpu::Queue, level: u32) -> Result<Vec<f32>, RenderError> {
        let (w, h) = ((self.size.0 >> level).max(1), (self.size.1 >> level).max(1));
        let row = (w * 4).div_ceil(256) * 256;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake depth pyramid readback"),
            size: (row * h) as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: level,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: Some(h) },
            },
            wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        );
        crate::blocking::submit(queue, [encoder.finish()]);
        crate::blocking::map_for_reading(device, &buffer, "depth pyramid readback")?;
        let out = {
            let view = buffer.slice(..).get_mapped_range().map_err(|e| RenderError::Gpu { what: e.to_string() })?;
            (0..h)
                .flat_map(|y| {
                    let start = (y * row) as usize;
                    bytemuck::cast_slice::<u8, f32>(&view[start..start + (w * 4) as usize]).to_vec()
                })
                .collect()
        };
        buffer.unmap();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_halve_down_to_one_texel() {
        assert_eq!(level_sizes(37, 23), [(37, 23), (18, 11), (9, 5), (4, 2), (2, 1), (1, 1)]);
        assert_eq!(level_sizes(1, 1), [(1, 1)]);
        assert_eq!(level_sizes(8, 1), [(8, 1), (4, 1), (2, 1), (1, 1)]);
    }

    #[test]
    fn level_struct_matches_the_shader() {
        use crate::shaders::tests::check_layout;
        use std::mem::offset_of;
        let level = [("sizes", offset_of!(PyramidLevel, sizes)), ("flags", offset_of!(PyramidLevel, flags))];
        assert_eq!(check_layout("PyramidLevel", size_of::<PyramidLevel>(), &level), 1);
    }
}
