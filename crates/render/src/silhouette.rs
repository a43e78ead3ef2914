//! Silhouette fins (fur thesis §4.1: "there is no algorithm to recognise the silhouette of an
//! object … a method for adding fins to the silhouette has to be developed"). The pack's fin edges
//! (borders and fur/bare edges, `furbake_bake::fin_edges`) carry fins always; the interior of a
//! furry surface has none, so a sphere's silhouette shows the shells stacking. Here the renderer
//! finds, every frame on the GPU, the interior edges on or near the silhouette for the current
//! camera and draws fins on them:
//!
//! - **Data** ([`interior_edges`]): every interior edge between two furry triangles, with both
//!   faces' third corners, derived at load time from the skin mesh's triangles (O(triangles))
//!   instead of being stored in the pack — no format change (golden checksums, fuzzing), and
//!   any pack baked before works. Edges that already carry an always-on fin, non-manifold edges
//!   (three or more triangles) and degenerate ones are skipped.
//! - **Selection** (`SilhouettePass`, `shaders/silhouette.wgsl`): one invocation per edge reads
//!   this frame's posed vertices (the skinning pass's output; the bind pose of a static pack),
//!   computes both unit face normals n₀, n₁ and the view vector v from the edge midpoint to the
//!   camera (in the object frame: the eye is brought back through the inverse model matrix), and
//!   selects the edge when n₀·v and n₁·v differ in sign (the silhouette) or
//!   m = min(|n₀·v|, |n₁·v|) < band (near it). Every edge writes its own instance slot (edge,
//!   fade), fade 0 when unselected, and a selected edge raises the `draw_indirect` instance count
//!   to at least its index + 1 with `atomicMax` (the count is reset in the encoder each frame with
//!   `clear_buffer`): the fins are drawn in edge order whatever order the invocations ran in, so
//!   their blending — and every image — is deterministic (an atomic append is not); the vertex
//!   shader collapses the unselected edges inside the drawn prefix. fade = 1 on the silhouette and 1 − m/band in the band, so a fin
//!   fades in as its edge nears the silhouette and never pops.
//! - **Draw** (`vs_silhouette_fin` in `shaders/fin.wgsl`): six vertices per instance, the same
//!   quad, extrusion, shear and fragment shading as the always-on fins, alpha × fade.
//! - **CPU reference**: [`silhouette_edges`], the same selection in plain Rust.

#[cfg(any(test, feature = "testing"))]
use furbake_draw::layout::SilhouetteEdge;
use furbake_draw::layout::SilhouetteParams;
use glam::Vec3;

use crate::RenderError;
use crate::upload::Upload;

/// Invocations per workgroup of `cs_silhouette`.
const WORKGROUP_SIZE: u32 = 64;

pub use furbake_draw::geometry::interior_edges;

#[cfg(feature = "testing")]
/// n₀·v and n₁·v of `edge` seen from `camera` (object frame), or `None` where a face has
/// collapsed. As `silhouette.wgsl` computes them, in f32.
pub fn edge_facing(positions: &[[f32; 3]], edge: &SilhouetteEdge, camera: [f32; 3]) -> Option<(f32, f32)> {
    let p = |i: u32| Vec3::from(positions[i as usize]);
    let (pa, pb, pc, pd) = (p(edge.a), p(edge.b), p(edge.c), p(edge.d));
    let n0 = (pb - pa).cross(pc - pa);
    let n1 = if edge.flags & 1 != 0 { (pb - pa).cross(pd - pa) } else { (pa - pb).cross(pd - pb) };
    let unit = |v: Vec3| if v.length() > 0.0 { v / v.length() } else { Vec3::ZERO };
    let (n0, n1) = (unit(n0), unit(n1));
    if n0 == Vec3::ZERO || n1 == Vec3::ZERO {
        return None;
    }
    let v = unit(Vec3::from(camera) - 0.5 * (pa + pb));
    Some((n0.dot(v), n1.dot(v)))
}

#[cfg(feature = "testing")]
/// The fade of an edge with facings `d0`, `d1`: 1 where they differ in sign (the silhouette),
/// 1 − min(|d0|, |d1|)/band within the band, 0 (not selected) elsewhere.
pub fn silhouette_fade(d0: f32, d1: f32, band: f32) -> f32 {
    let m = d0.abs().min(d1.abs());
    if (d0 > 0.0) != (d1 > 0.0) {
        1.0
    } else if m < band {
        1.0 - m / band
    } else {
        0.0
    }
}

#[cfg(feature = "testing")]
/// The CPU reference of the GPU selection: every edge (index into `edges`) on or near the
/// silhouette of the surface `positions` (welded vertices, object frame; the posed ones for an
/// animated pack) seen from `camera_pos` (object frame), with its fade, in edge order.
pub fn silhouette_edges(
    positions: &[[f32; 3]],
    edges: &[SilhouetteEdge],
    camera_pos: [f32; 3],
    band: f32,
) -> Vec<(u32, f32)> {
    edges
        .iter()
        .enumerate()
        .filter_map(|(i, e)| {
            let (d0, d1) = edge_facing(positions, e, camera_pos)?;
            let fade = silhouette_fade(d0, d1, band);
            (fade > 0.0).then_some((i as u32, fade))
        })
        .collect()
}

/// The per-renderer GPU side of the selection: parameters, the instance list, the indirect draw
/// arguments, and the bind groups of the compute pass and of the silhouette fin draw.
pub(crate) struct SilhouettePass {
    edge_count: u32,
    band: f32,
    params: wgpu::Buffer,
    #[cfg(feature = "testing")]
    instances: wgpu::Buffer,
    args: wgpu::Buffer,
    compute_group: wgpu::BindGroup,
    draw_group: wgpu::BindGroup,
    pipeline: wgpu::ComputePipeline,
    workgroups: (u32, u32),
}

impl SilhouettePass {
    /// `edges` and `colors` are the shared asset's buffers, `vertices` the posed (or rest)
    /// vertices this renderer's surface stands on.
    pub(crate) fn new(
        cache: &crate::PipelineCache,
        edges: &wgpu::Buffer,
        colors: &wgpu::Buffer,
        vertices: &wgpu::Buffer,
        edge_count: u32,
        band: f32,
    ) -> Result<SilhouettePass, RenderError> {
        let device = cache.device();
        let limits = device.limits();
        let bytes = edge_count.max(1) as u64 * 8;
        if bytes > limits.max_storage_buffer_binding_size {
            return Err(RenderError::Limit {
                what: "silhouette instance bytes",
                value: bytes,
                limit: limits.max_storage_buffer_binding_size,
            });
        }
        let groups = edge_count.div_ceil(WORKGROUP_SIZE).max(1);
        let max = limits.max_compute_workgroups_per_dimension;
        let workgroups = if groups <= max { (groups, 1) } else { (max, groups.div_ceil(max)) };
        let pipeline = cache.silhouette_compute()?;
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake silhouette params"),
            size: std::mem::size_of::<SilhouetteParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let instances = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake silhouette instances"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        use wgpu::util::DeviceExt;
        let args = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("furbake silhouette draw args"),
            contents: bytemuck::cast_slice(&[6u32, 0, 0, 0]),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
        });
        fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
        }
        let compute_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake silhouette selection"),
            layout: cache.silhouette_compute_layout(),
            entries: &[entry(0, &params), entry(1, edges), entry(2, vertices), entry(3, &instances), entry(4, &args)],
        });
        let draw_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake silhouette fins"),
            layout: cache.silhouette_draw_layout(),
            entries: &[entry(0, edges), entry(1, &instances), entry(2, vertices), entry(3, colors)],
        });
        Ok(SilhouettePass {
            edge_count,
            band,
            params,
            #[cfg(feature = "testing")]
            instances,
            args,
            compute_group,
            draw_group,
            pipeline,
            workgroups,
        })
    }

    /// Writes this frame's camera (object frame) through `upload`; [`SilhouettePass::record`]
    /// then selects with it.
    pub(crate) fn write_camera(&self, upload: &mut Upload<'_>, camera_obj: Vec3) {
        let params = SilhouetteParams {
            camera_obj: [camera_obj.x, camera_obj.y, camera_obj.z, 1.0],
            band: self.band,
            edge_count: self.edge_count,
            pad0: 0,
            pad1: 0,
        };
        upload.write(&self.params, 0, bytemuck::bytes_of(&params));
    }

    /// Records the counter reset and the selection dispatch into `encoder`. No submission, no
    /// wait.
    pub(crate) fn record(&self, encoder: &mut wgpu::CommandEncoder) {
        // instance_count (bytes 4..8 of DrawIndirectArgs) back to 0; vertex_count stays 6.
        encoder.clear_buffer(&self.args, 4, Some(4));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("furbake silhouette"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.compute_group, &[]);
        pass.dispatch_workgroups(self.workgroups.0, self.workgroups.1, 1);
    }

    /// Draws the selected fins (pipeline and group 0 set by the caller).
    pub(crate) fn draw(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.set_bind_group(1, &self.draw_group, &[]);
        pass.draw_indirect(&self.args, 0);
    }

    #[cfg(feature = "testing")]
    /// Copies the counter and the instance list into `readback` buffers (test readback).
    pub(crate) fn copy_out(&self, encoder: &mut wgpu::CommandEncoder, args: &wgpu::Buffer, instances: &wgpu::Buffer) {
        encoder.copy_buffer_to_buffer(&self.args, 0, args, 0, 16);
        encoder.copy_buffer_to_buffer(&self.instances, 0, instances, 0, self.instances.size());
    }

    #[cfg(feature = "testing")]
    pub(crate) fn instance_bytes(&self) -> u64 {
        self.instances.size()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use furbake_formats::sections::skin_mesh::SkinMesh;

    fn mesh(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> SkinMesh {
        let n = positions.len();
        SkinMesh {
            normals: vec![[0.0, 0.0, 1.0]; n],
            colors: vec![[1.0; 4]; n],
            fur_mask: vec![1; triangles.len()],
            positions,
            triangles,
            corner_texcoords: Vec::new(),
            stats: Default::default(),
        }
    }

    #[test]
    fn a_tetrahedron_has_six_interior_edges_and_a_silhouette() {
        let m = mesh(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        );
        let edges = interior_edges(&m, None);
        assert_eq!(edges.len(), 6);
        assert!(edges.iter().all(|e| e.flags == 0), "consistently wound");
        // Seen from far along +x+y+z only face 1-2-3 faces the camera: its three edges are the
        // silhouette, the three at the origin lie between faces turned away.
        let sel = silhouette_edges(&m.positions, &edges, [10.0, 10.0, 10.0], 0.0);
        assert_eq!(sel.len(), 3);
        for (i, fade) in sel {
            let e = edges[i as usize];
            assert!(e.a != 0 && e.b != 0, "{e:?}");
            assert_eq!(fade, 1.0);
        }
    }

    #[test]
    fn non_manifold_bare_and_fin_edges_are_skipped() {
        let mut m = mesh(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        assert!(interior_edges(&m, None).is_empty(), "edge 0–1 has three faces, the rest one");
        m.triangles.pop();
        m.fur_mask.pop();
        assert_eq!(interior_edges(&m, None).len(), 1);
        m.fur_mask[1] = 0;
        assert!(interior_edges(&m, None).is_empty(), "a fur/bare edge carries an always-on fin");
    }

    /// The silhouette structs mirror their WGSL declarations (see `crate::shaders`'s layout tests).
    #[test]
    fn silhouette_structs_match_the_shaders() {
        use std::mem::{offset_of, size_of};

        use crate::shaders::tests::check_layout;
        let edge = [
            ("a", offset_of!(SilhouetteEdge, a)),
            ("b", offset_of!(SilhouetteEdge, b)),
            ("c", offset_of!(SilhouetteEdge, c)),
            ("d", offset_of!(SilhouetteEdge, d)),
            ("corner_a", offset_of!(SilhouetteEdge, corner_a)),
            ("corner_b", offset_of!(SilhouetteEdge, corner_b)),
            ("flags", offset_of!(SilhouetteEdge, flags)),
            ("pad0", offset_of!(SilhouetteEdge, pad0)),
        ];
        // Read by the selection (silhouette.wgsl) and the silhouette fin draw (fin.wgsl).
        assert_eq!(check_layout("SilhouetteEdge", size_of::<SilhouetteEdge>(), &edge), 2);
        let params = [
            ("camera_obj", offset_of!(SilhouetteParams, camera_obj)),
            ("band", offset_of!(SilhouetteParams, band)),
            ("edge_count", offset_of!(SilhouetteParams, edge_count)),
            ("pad0", offset_of!(SilhouetteParams, pad0)),
            ("pad1", offset_of!(SilhouetteParams, pad1)),
        ];
        assert_eq!(check_layout("SilhouetteParams", size_of::<SilhouetteParams>(), &params), 1);
    }
}
