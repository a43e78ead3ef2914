//! Grass at scale (grass thesis §5.3 and ch. 7; Jahrmann & Wimmer 2017): which blades a frame
//! draws and at what level of detail. The GPU side is `shaders/blade_cull.wgsl`, recorded by
//! [`crate::BladeRenderer::prepare`] and drawn with one `draw_indexed_indirect` per level; this
//! module holds what the CPU prepares for it — the levels' index lists, the reach of any pose, the
//! clusters' bounds, the frame's [`CullUniforms`] — and [`CullReference`], the CPU twin of the
//! culling passes that tests compare the GPU's instance lists with.
//!
//! Two levels: each cluster (a cell of the blade field's grid) is tested as a box holding every
//! pose of its blades against the view frustum and the max distance; then each blade of a visible
//! cluster is culled by the max distance, by distance thinning (kept with probability
//! `(start/d)²`, at least the min density, by a fixed random number per blade; the kept blades are
//! drawn wider by the inverse so coverage stays), by orientation (seen edge-on) and by the frustum
//! (a sphere around the root that holds every pose). A surviving blade's level of detail falls
//! with distance: every segment, every second Bézier node, every fourth — the same nodes of the
//! same reference blade, so the coarse levels decode fewer vertices of the same poses — and each
//! blade switches at its own distance inside a band around each LOD distance (dithered
//! transitions: no visible line where the level changes). Distances are world metres, divided by
//! the model matrix's scale into the pack frame.

use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::keyframe_table::KeyframeTable;
pub use furbake_runtime::GrassCulling;
use glam::{Mat4, Vec3, Vec4};

use crate::shaders::FrameUniforms;

/// Most levels of detail (full, half and quarter of the segments).
pub const MAX_LODS: usize = 3;
/// Blades per block of the culling passes (one workgroup).
pub(crate) const BLOCK: u32 = 256;
/// First word of the block counts in the work buffer.
pub(crate) const BLOCKS_AT: u64 = 32;
/// First word of the instance lists in the instance buffer.
pub(crate) const LISTS_AT: u64 = 4;
#[cfg(feature = "testing")]
/// The per-blade random numbers' salts (as `grass_common.wgsl`).
const SALT_THINNING: u32 = 0x68e3_1da4;
#[cfg(feature = "testing")]
const SALT_LOD: u32 = 0xb529_7a4d;

/// The frame's culling parameters as `grass_common.wgsl` reads them (`CullUniforms`).
/// The share of its width a blade seen edge-on still shows once the draw thickens it across the
/// view (`vs_blade` in `shaders/blades.wgsl`; Ghost of Tsushima's view-space thickening of
/// edge-on blades): blades between the orientation cull's `min_visible_width` and this are
/// widened to it, so a field seen along its blades' faces does not thin out into lines. The
/// frustum tests pad each blade by this share of its half-width more.
pub const EDGE_ON_WIDTH: f32 = 0.35;

/// The culling parameters of one frame as `blade_cull.wgsl` reads them (`CullUniforms`): the
/// frame's planes and eye in the pack frame, the level-of-detail and thinning distances, the
/// blade's reach and the draw's index ranges.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CullUniforms {
    /// The six clip planes of view_proj × model, normalised; a degenerate one is `(0, 0, 0, 1)`.
    pub planes: [[f32; 4]; 6],
    /// Eye in the pack frame (xyz); w = 1 when culling is on.
    pub eye: [f32; 4],
    /// LOD 1 and LOD 2 distances, their dither bands (pack metres).
    pub lod: [f32; 4],
    /// Max distance², thinning start, min density, 1 − min visible width² (1: off).
    pub distance: [f32; 4],
    /// Reach of any pose and largest reference half-width (blade lengths), [`EDGE_ON_WIDTH`],
    /// unused.
    pub shape: [f32; 4],
    /// Index count per LOD.
    pub index_count: [u32; 4],
    /// First index per LOD.
    pub first_index: [u32; 4],
    /// Blades, clusters, blocks, levels of detail.
    pub counts: [u32; 4],
    /// view_proj × model (the pack frame to clip space), columns.
    pub clip: [[f32; 4]; 4],
    /// The view's depth pyramid ([`crate::DepthPyramid`]): width, height, levels and flags (1:
    /// occlusion test on, 2: reversed depth); zero without one.
    pub occlusion: [u32; 4],
}

/// A blade field's levels of detail and extents, derived once at load.
#[derive(Clone, Debug, PartialEq)]
pub struct BladeLods {
    /// Every level's triangle indices, concatenated; level `l`'s indices are offset by
    /// `l × vertex_count` (the vertex shader splits them back).
    pub indices: Vec<u32>,
    /// Levels (1 when the table's blade is not the quad strip the bake writes, or has one
    /// segment).
    pub count: u32,
    /// Segments per level.
    pub segments: [u32; MAX_LODS],
    /// Index count per level.
    pub index_count: [u32; 4],
    /// First index per level.
    pub first_index: [u32; 4],
    /// Largest distance of any vertex of any stored pose (and of the reference) from the root,
    /// in blade lengths: a blade of height scale `h` stays within `h × reach` of its root in
    /// every pose, nearest or linearly blended (a convex combination of stored poses).
    pub reach: f32,
    /// Largest |x| of the reference blade (half its width), blade lengths.
    pub half_width: f32,
}

impl BladeLods {
    /// The levels of `table`'s blade: when its vertices and triangles are the bake's quad strip
    /// (`4S` vertices, segment `k` = vertices `4k..4k+4`, triangles `[q, q+1, q+3]`,
    /// `[q, q+3, q+2]`), level `l` joins `2^l` segments into one quad from the bottom vertices of
    /// the first to the top vertices of the last (the last quad may join fewer), while that
    /// lowers the segment count, up to [`MAX_LODS`] levels; otherwise one level, the table's
    /// triangles.
    pub fn new(table: &KeyframeTable) -> BladeLods {
        let v = table.vertex_count();
        let s = table.segments as usize;
        let strip = s > 0
            && v == 4 * s
            && table.triangles.len() == 2 * s
            && (0..s).all(|k| {
                let q = 4 * k as u32;
                table.triangles[2 * k] == [q, q + 1, q + 3] && table.triangles[2 * k + 1] == [q, q + 3, q + 2]
            });
        let mut indices: Vec<u32> = table.triangles.iter().flatten().copied().collect();
        let mut index_count = [indices.len() as u32, 0, 0, 0];
        let mut first_index = [0u32; 4];
        let mut segments = [table.segments, 0, 0];
        let mut count = 1;
        if strip {
            for l in 1..MAX_LODS {
                let stride = 1usize << l;
                let quads = s.div_ceil(stride);
                if quads >= s.div_ceil(stride / 2) {
                    break;
                }
                first_index[l] = indices.len() as u32;
                let offset = (l * v) as u32;
                for j in 0..quads {
                    let (lo, hi) = (j * stride, ((j + 1) * stride).min(s) - 1);
                    let (lb, rb) = (4 * lo as u32, 4 * lo as u32 + 1);
                    let (lt, rt) = (4 * hi as u32 + 2, 4 * hi as u32 + 3);
                    indices.extend([lb, rb, rt, lb, rt, lt].map(|i| i + offset));
                }
                index_count[l] = indices.len() as u32 - first_index[l];
                segments[l] = quads as u32;
                count += 1;
            }
        }
        let (reach, half_width) = pose_reach(table);
        BladeLods { indices, count, segments, index_count, first_index, reach, half_width }
    }
}

/// The reach of every stored pose (see [`BladeLods::reach`]) and the reference half-width. Uses
/// the CPU decoder when the table decodes; a table it refuses is refused by the renderer too.
fn pose_reach(table: &KeyframeTable) -> (f32, f32) {
    let reference: Vec<Vec3> = table.reference_positions.iter().map(|p| Vec3::from(*p)).collect();
    let half_width = reference.iter().map(|p| p.x.abs()).filter(|x| x.is_finite()).fold(0.0f32, f32::max);
    let mut reach = reference.iter().map(|p| p.length()).filter(|x| x.is_finite()).fold(0.0f32, f32::max);
    if let Ok(decoder) = furbake_grass::KeyframeDecoder::new(table) {
        let g = decoder.grid();
        for magnitude in 1..=g.magnitudes {
            for angle in 0..g.angles {
                let key = furbake_grass::PoseKey { magnitude, angle };
                for (v, r) in reference.iter().enumerate() {
                    let l = (*r + decoder.displacement(key, v)).length();
                    if l.is_finite() {
                        reach = reach.max(l);
                    }
                }
            }
        }
    }
    // Room for the f32 rounding of the blend and of the shaders' arithmetic.
    (reach * (1.0 + 1e-4) + 1e-6, half_width)
}

/// Per cluster: its blades' root bounds (`min`, with the tallest height scale in w) and
/// (`max`, 0); an empty cluster has min > max.
pub(crate) fn cluster_bounds(field: &BladeField) -> Vec<[f32; 4]> {
    let clusters = field.grid.clusters();
    let mut bounds = vec![[f32::INFINITY, f32::INFINITY, f32::INFINITY, 0.0]; 2 * clusters];
    for k in 0..clusters {
        bounds[2 * k + 1] = [f32::NEG_INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY, 0.0];
    }
    for (b, p) in field.positions.iter().enumerate() {
        let c = field.cluster[b] as usize;
        if c >= clusters || !p.iter().all(|x| x.is_finite()) {
            continue;
        }
        for a in 0..3 {
            bounds[2 * c][a] = bounds[2 * c][a].min(p[a]);
            bounds[2 * c + 1][a] = bounds[2 * c + 1][a].max(p[a]);
        }
        let h = field.height_scale[b];
        if h.is_finite() {
            bounds[2 * c][3] = bounds[2 * c][3].max(h);
        }
    }
    // An empty cluster keeps +inf > -inf: culled. Shaders and bounds checks want finite values.
    for k in 0..clusters {
        if bounds[2 * k][0] > bounds[2 * k + 1][0] {
            bounds[2 * k] = [1.0, 1.0, 1.0, 0.0];
            bounds[2 * k + 1] = [0.0, 0.0, 0.0, 0.0];
        }
    }
    bounds
}

/// The plane `row3 + sign·row_k` of `m` (Gribb–Hartmann), normalised to a signed distance.
fn plane(m: &Mat4, row: Option<(usize, f32)>, near: bool) -> [f32; 4] {
    let r = |i| m.row(i);
    let p: Vec4 = match (row, near) {
        (Some((k, s)), _) => r(3) + r(k) * s,
        // wgpu clip space: 0 ≤ z ≤ w.
        (None, true) => r(2),
        (None, false) => r(3) - r(2),
    };
    let n = p.truncate().length();
    if n.is_finite() && n > 1e-20 { (p / n).to_array() } else { [0.0, 0.0, 0.0, 1.0] }
}

impl CullUniforms {
    /// The parameters of one frame: `frame`'s view-projection and model matrix (the field's pack
    /// frame → world: rotation, translation, uniform scale), `culling`'s distances (world metres)
    /// and the field's `lods`, `blades` and `clusters`.
    pub fn new(frame: &FrameUniforms, culling: &GrassCulling, lods: &BladeLods, blades: u32, clusters: u32) -> Self {
        let model = frame.model();
        let m = Mat4::from_cols_array_2d(&frame.view_proj) * model;
        let planes = [
            plane(&m, Some((0, 1.0)), false),
            plane(&m, Some((0, -1.0)), false),
            plane(&m, Some((1, 1.0)), false),
            plane(&m, Some((1, -1.0)), false),
            plane(&m, None, true),
            plane(&m, None, false),
        ];
        // World metres per pack metre (the model's uniform scale).
        let scale = model.x_axis.truncate().length();
        let scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
        let eye = model.inverse().transform_point3(Vec3::from_slice(&frame.camera_pos[..3]));
        let eye = if eye.is_finite() { eye } else { Vec3::ZERO };
        let c = culling;
        let [d1, d2] = c.lod_distances_m.map(|d| d / scale);
        let max = c.max_distance_m / scale;
        let w = c.min_visible_width;
        CullUniforms {
            planes,
            eye: [eye.x, eye.y, eye.z, c.enabled as u32 as f32],
            lod: [d1, d2, d1 * c.lod_transition, d2 * c.lod_transition],
            distance: [max * max, c.thinning_start_m / scale, c.min_density, 1.0 - w * w],
            shape: [lods.reach, lods.half_width, EDGE_ON_WIDTH, 0.0],
            index_count: lods.index_count,
            first_index: lods.first_index,
            counts: [blades, clusters, blades.div_ceil(BLOCK), lods.count],
            clip: m.to_cols_array_2d(),
            occlusion: [0; 4],
        }
    }
}

#[cfg(feature = "testing")]
/// What the culling passes decided for one frame: per level of detail, the blades drawn, in
/// increasing blade order (as the GPU's instance lists).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CullLists {
    /// Blade indices per level.
    pub lods: [Vec<u32>; MAX_LODS],
}

#[cfg(feature = "testing")]
impl CullLists {
    /// Blades drawn per level.
    pub fn counts(&self) -> [usize; MAX_LODS] {
        self.lods.each_ref().map(Vec::len)
    }

    /// Blades drawn.
    pub fn drawn(&self) -> usize {
        self.counts().iter().sum()
    }
}

#[cfg(feature = "testing")]
/// The CPU reference of the culling passes (`cs_cull_clusters`, `cs_cull_blades`): the same
/// tests in the same f32 arithmetic on the same parameters ([`CullUniforms::new`]).
pub struct CullReference {
    roots: Vec<[f32; 4]>,
    yaw: Vec<[f32; 2]>,
    cluster: Vec<u32>,
    bounds: Vec<[f32; 4]>,
    lods: BladeLods,
}

#[cfg(feature = "testing")]
/// The result of [`CullReference::classify`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CullDecision {
    /// The lists the GPU must produce.
    pub lists: CullLists,
    /// Blades whose decision rests on a comparison within a relative 1e-5 of its threshold
    /// (where the GPU's rounding of a division, square root or dot product may decide the other
    /// way); tests allow these, and only these, to differ.
    pub near_boundary: Vec<u32>,
    /// Clusters that passed the cluster test.
    pub visible_clusters: usize,
}

#[cfg(feature = "testing")]
/// `a` within a relative `1e-5` of `b`.
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-5 * a.abs().max(b.abs()).max(1e-6)
}

#[cfg(feature = "testing")]
/// `blade_random` of `grass_common.wgsl`.
pub fn blade_random(b: u32, salt: u32) -> f32 {
    let mut x = b.wrapping_mul(0x9e37_79b9) ^ salt;
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[cfg(feature = "testing")]
/// `thinning_keep` of `grass_common.wgsl`.
pub fn thinning_keep(start: f32, min_density: f32, d: f32) -> f32 {
    let s = start / d.max(1e-30);
    (s * s).max(min_density).min(1.0)
}

#[cfg(feature = "testing")]
fn dot3(a: [f32; 4], b: Vec3) -> f32 {
    a[0] * b.x + a[1] * b.y + a[2] * b.z
}

#[cfg(feature = "testing")]
impl CullReference {
    /// The reference for `field` drawn with `table`'s blade.
    pub fn new(field: &BladeField, table: &KeyframeTable) -> CullReference {
        CullReference {
            roots: (0..field.blade_count())
                .map(|b| {
                    let [x, y, z] = field.positions[b];
                    [x, y, z, field.height_scale[b]]
                })
                .collect(),
            yaw: field.yaw_rad.iter().map(|y| [y.cos(), y.sin()]).collect(),
            cluster: field.cluster.clone(),
            bounds: cluster_bounds(field),
            lods: BladeLods::new(table),
        }
    }

    /// The levels of detail of the field's blade.
    pub fn lods(&self) -> &BladeLods {
        &self.lods
    }

    /// The frame's parameters (as the renderer uploads them).
    pub fn params(&self, frame: &FrameUniforms, culling: &GrassCulling) -> CullUniforms {
        CullUniforms::new(frame, culling, &self.lods, self.roots.len() as u32, (self.bounds.len() / 2) as u32)
    }

    /// The blades drawn for `frame` under `culling`, per level of detail.
    pub fn classify(&self, frame: &FrameUniforms, culling: &GrassCulling) -> CullDecision {
        let p = self.params(frame, culling);
        let mut out = CullDecision::default();
        if p.eye[3] == 0.0 {
            out.lists.lods[0] = (0..self.roots.len() as u32).collect();
            return out;
        }
        let eye = Vec3::from_slice(&p.eye[..3]);
        let widening = 1.0 / p.distance[2] - 1.0;
        let clusters: Vec<(bool, bool)> = (0..self.bounds.len() / 2)
            .map(|c| {
                let (lo, hi) = (self.bounds[2 * c], self.bounds[2 * c + 1]);
                if lo[0] > hi[0] {
                    return (false, false);
                }
                let r = lo[3] * (p.shape[0] + (widening + p.shape[2] * (1.0 + widening)) * p.shape[1]);
                let blo = Vec3::new(lo[0], lo[1], lo[2]) - Vec3::splat(r);
                let bhi = Vec3::new(hi[0], hi[1], hi[2]) + Vec3::splat(r);
                let (mut visible, mut near) = (true, false);
                for pl in &p.planes {
                    let corner = Vec3::select(Vec3::new(pl[0], pl[1], pl[2]).cmpgt(Vec3::ZERO), bhi, blo);
                    let s = dot3(*pl, corner) + pl[3];
                    near |= close(s, 0.0) || close(dot3(*pl, corner), -pl[3]);
                    if s < 0.0 {
                        visible = false;
                    }
                }
                let q = eye.clamp(blo, bhi) - eye;
                let q2 = q.dot(q);
                near |= close(q2, p.distance[0]);
                if q2 > p.distance[0] {
                    visible = false;
                }
                (visible, near)
            })
            .collect();
        out.visible_clusters = clusters.iter().filter(|c| c.0).count();
        for b in 0..self.roots.len() {
            let (lod, mut near) = self.classify_blade(b as u32, &p);
            let (visible, cluster_near) = clusters.get(self.cluster[b] as usize).copied().unwrap_or((false, false));
            // A cluster close to its boundary matters only for a blade its own tests keep.
            near |= cluster_near && lod.is_some();
            if near {
                out.near_boundary.push(b as u32);
            }
            if let (true, Some(l)) = (visible, lod) {
                out.lists.lods[l as usize].push(b as u32);
            }
        }
        out
    }

    /// The blade tests of `classify` in `blade_cull.wgsl` (after its cluster test): the LOD or
    /// `None`, and whether a comparison was close to its threshold.
    fn classify_blade(&self, b: u32, p: &CullUniforms) -> (Option<u32>, bool) {
        let [x, y, z, h] = self.roots[b as usize];
        let root = Vec3::new(x, y, z);
        let eye = Vec3::from_slice(&p.eye[..3]);
        let to_eye = eye - root;
        let d2 = to_eye.x * to_eye.x + to_eye.y * to_eye.y + to_eye.z * to_eye.z;
        let mut near = close(d2, p.distance[0]);
        if d2 > p.distance[0] {
            return (None, near);
        }
        let d = d2.sqrt();
        let keep = thinning_keep(p.distance[1], p.distance[2], d);
        let u = blade_random(b, SALT_THINNING);
        near |= close(u, keep);
        if u >= keep {
            return (None, near);
        }
        let [c, s] = self.yaw[b as usize];
        let across = to_eye.x * c - to_eye.z * s;
        if p.distance[3] < 1.0 {
            near |= close(across * across, p.distance[3] * d2);
            if across * across > p.distance[3] * d2 {
                return (None, near);
            }
        }
        let r = h * (p.shape[0] + (1.0 / keep - 1.0 + p.shape[2] / keep) * p.shape[1]);
        for pl in &p.planes {
            let s = dot3(*pl, root) + pl[3];
            near |= close(s, -r) || close(dot3(*pl, root), -pl[3] - r);
            if s < -r {
                return (None, near);
            }
        }
        let u = blade_random(b, SALT_LOD) - 0.5;
        let mut lod = 0;
        let t1 = p.lod[0] + u * p.lod[2];
        let t2 = p.lod[1] + u * p.lod[3];
        if p.counts[3] > 1 {
            near |= close(d, t1);
            if d >= t1 {
                lod = 1;
            }
        }
        if p.counts[3] > 2 {
            near |= close(d, t2);
            if d >= t2 {
                lod = 2;
            }
        }
        (Some(lod), near)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, Symmetry};
    use furbake_grass::keyframes::PoseGridSettings;

    fn table(segments: u32) -> KeyframeTable {
        let grid = PoseGridSettings { poses: 40, ..Default::default() }.resolve(Symmetry::XZ).unwrap();
        let shape = furbake_grass::BladeShape { segments, ..Default::default() };
        let blade = furbake_grass::build_reference_blade(&shape).unwrap();
        let poses = furbake_grass::simulate_poses(&blade, &furbake_grass::BladeMaterial::default(), grid).unwrap();
        let stages = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
        furbake_grass::compress_poses(&poses, Symmetry::XZ, stages, DisplacementEncoding::Snorm16).unwrap()
    }

    #[test]
    fn eight_segments_give_eight_four_and_two_segment_levels_on_the_same_nodes() {
        let t = table(8);
        let lods = BladeLods::new(&t);
        assert_eq!(lods.count, 3);
        assert_eq!(lods.segments, [8, 4, 2]);
        assert_eq!(lods.index_count[..3], [48, 24, 12]);
        assert_eq!(lods.first_index[..3], [0, 48, 72]);
        // Level 2's first quad: the bottom of segment 0 and the top of segment 3 (node 4 of 8),
        // offset by two blades' vertices.
        assert_eq!(lods.indices[72..78], [0, 1, 15, 0, 15, 14].map(|i| i + 64));
        // Node 4 of 8 is node 2 of 4: the top of segment 3 is where segment 4 starts.
        assert_eq!(t.reference_positions[14], t.reference_positions[16]);
        // Every pose stays within one blade length and a half-width of the root.
        assert!(lods.reach >= 1.0 && lods.reach < 1.05, "{}", lods.reach);
        assert!((lods.half_width - 0.03).abs() < 1e-6, "{}", lods.half_width);
    }

    #[test]
    fn odd_segment_counts_join_what_is_left_and_stop_when_nothing_is_saved() {
        assert_eq!(BladeLods::new(&table(3)).segments, [3, 2, 1]);
        let two = BladeLods::new(&table(2));
        assert_eq!((two.count, two.segments), (2, [2, 1, 0]));
        assert_eq!(BladeLods::new(&table(1)).count, 1);
        // Not the bake's strip: one level.
        let mut t = table(4);
        t.triangles.swap(0, 1);
        assert_eq!(BladeLods::new(&t).count, 1);
    }

    #[test]
    fn thinning_keeps_everything_before_its_start_and_the_min_density_far_away() {
        assert_eq!(thinning_keep(20.0, 0.25, 10.0), 1.0);
        assert_eq!(thinning_keep(20.0, 0.25, 20.0), 1.0);
        assert!((thinning_keep(20.0, 0.25, 30.0) - 4.0 / 9.0).abs() < 1e-6);
        assert_eq!(thinning_keep(20.0, 0.25, 1000.0), 0.25);
        // The random numbers are uniform: about a quarter of a million blades fall below 0.25.
        let below = (0..1_000_000u32).filter(|&b| blade_random(b, SALT_THINNING) < 0.25).count();
        assert!((below as f64 - 250_000.0).abs() < 2_000.0, "{below}");
    }

    /// `CullUniforms` mirrors its WGSL declaration (see `crate::shaders`'s layout tests).
    #[test]
    fn cull_uniforms_match_the_shaders() {
        use std::mem::{offset_of, size_of};

        use crate::shaders::tests::check_layout;
        type C = CullUniforms;
        let cull = [
            ("planes", offset_of!(C, planes)),
            ("eye", offset_of!(C, eye)),
            ("lod", offset_of!(C, lod)),
            ("distance", offset_of!(C, distance)),
            ("shape", offset_of!(C, shape)),
            ("index_count", offset_of!(C, index_count)),
            ("first_index", offset_of!(C, first_index)),
            ("counts", offset_of!(C, counts)),
            ("clip", offset_of!(C, clip)),
            ("occlusion", offset_of!(C, occlusion)),
        ];
        assert_eq!(check_layout("CullUniforms", size_of::<C>(), &cull), 2, "grass_common.wgsl, in both");
    }

    /// The culling passes' workgroups are one block wide (the dispatch sizes computed here).
    #[test]
    fn the_culling_workgroups_are_one_block() {
        for name in ["cs_cull_blades", "cs_scan_blocks", "cs_compact", "cs_pose_all"] {
            assert_eq!(crate::shaders::tests::workgroup_width(name), Some(BLOCK), "{name}");
        }
    }
}
