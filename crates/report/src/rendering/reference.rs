//! The ground truth the shells and fins approximate: a CPU ray-marcher of the bake's hair volume
//! itself, before it is sliced into the shell atlas (fur thesis §3.1, eq. 3.1–3.2: every hair a
//! curve `root + direction · dmax · h^n · w1` with a tapering circular cross-section, cut at its
//! length), laid on the mesh as the renderer lays the atlas (§3.2): over each furry triangle the
//! fur is the prism between the skin and the outermost shell, the shell at relative height t
//! being the triangle `p_i + t · L · n_i` (eq. 3.36 at rest, s = n) with the triangle's own UVs
//! (fig. 3.18–3.19), so the point of barycentrics b at height t is texel `fract(Σ b_i uv_i) · res`
//! of the hair tile at height t.
//!
//! Per pixel, `k × k` jittered samples (deterministic in the seed and the pixel) are traced
//! through the same camera as the GPU frame (the inverse of `View::view_proj`). A ray finds its
//! candidate prisms in a bounding-volume hierarchy, the nearest skin triangle exactly, and then
//! marches through each prism's slab towards the skin by sphere tracing: the step is a
//! conservative bound of the distance to the nearest hair, from a uniform grid over the (tiling)
//! hair tile that lists the hairs near each cell. The first hair entered is the sample's colour,
//! shaded with the shells' function ([`super::shade`]) at the hit's continuous height; a sample
//! that reaches the skin takes the skin's shading, one that misses everything the background.
//!
//! What the reference shares with the shells on purpose, so that the measured difference is the
//! slicing (layer count, fins, blending, mip filtering) and not the model: the shading
//! parameters and light, the hair direction (`strand_tangent` at rest is the normal, the shells'
//! tangent), the self-shadow table (the value of the slab the hit lies in), the noise texel and
//! the prism mapping. What it does not share: heights are continuous (the shells draw
//! `(i + 1)/N`), hairs are opaque discs of their true radius (the atlas stores anti-aliased alpha
//! and the shells blend it), and a pixel integrates many samples.

use std::sync::Arc;

use furbake_bake::rng::{SplitMix64, derive_seed};
use furbake_bake::volume::{CoatKind, HairSet, grow_hairs};
use furbake_formats::sections::shell_atlas::ShellAtlas;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use glam::{Mat4, Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::shade::ShadeSettings;

/// Why a reference scene cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// The sections disagree (one UV triple per triangle, one normal and colour per vertex).
    #[error("reference scene: {0}")]
    Sections(String),
    /// A render parameter is out of range (size, samples).
    #[error("reference render: {0}")]
    Parameter(String),
}

/// One hair as the marcher needs it, in texels of the tile (heights as fractions of the fur).
#[derive(Clone, Copy, Debug)]
struct Hair {
    root: Vec2,
    /// `direction · dmax · w1`: the lateral offset at h = 1 (eq. 3.2).
    bend: Vec2,
    length: f32,
    radius: f32,
    /// Radius lost per unit of height (`r0 · taper / l`).
    taper_per_h: f32,
    coat: u8,
}

/// The hairs of the tile in a uniform grid of `cells × cells` cells of `cell` texels, each listing
/// (copies of) every hair whose curve passes within `margin` texels of it, wrapping at the border.
struct HairGrid {
    res: f32,
    cells: usize,
    cell: f32,
    margin: f32,
    exponents: [f32; 2],
    start: Vec<u32>,
    hairs: Vec<Hair>,
}

impl HairGrid {
    fn new(set: &HairSet) -> HairGrid {
        let res = set.resolution as f32;
        let cells = (set.resolution as usize / 4).max(1);
        let cell = res / cells as f32;
        let margin = 0.5 * cell;
        let mut lists: Vec<Vec<Hair>> = vec![Vec::new(); cells * cells];
        for i in 0..set.len() {
            let shape = set.shapes[set.coat[i] as usize];
            let root = Vec2::new(set.root_x[i], set.root_y[i]);
            let bend = set.direction[i].unit() * shape.max_deviation_texels * set.bend[i];
            let length = set.length[i];
            let hair = Hair {
                root,
                bend,
                length,
                radius: set.radius_texels[i],
                taper_per_h: set.radius_texels[i] * shape.taper / length,
                coat: set.coat[i] as u8,
            };
            let tip = root + bend * length.powf(shape.curvature_exponent);
            let reach = hair.radius + margin;
            let (lo, hi) = (root.min(tip) - Vec2::splat(reach), root.max(tip) + Vec2::splat(reach));
            let (cx0, cx1) = ((lo.x / cell).floor() as i64, (hi.x / cell).floor() as i64);
            let (cy0, cy1) = ((lo.y / cell).floor() as i64, (hi.y / cell).floor() as i64);
            let n = cells as i64;
            for cy in cy0..=cy1.min(cy0 + n - 1) {
                for cx in cx0..=cx1.min(cx0 + n - 1) {
                    lists[cy.rem_euclid(n) as usize * cells + cx.rem_euclid(n) as usize].push(hair);
                }
            }
        }
        let mut start = Vec::with_capacity(lists.len() + 1);
        let mut hairs = Vec::new();
        for l in &lists {
            start.push(hairs.len() as u32);
            hairs.extend_from_slice(l);
        }
        start.push(hairs.len() as u32);
        let exponents = [set.shapes[0].curvature_exponent, set.shapes[1].curvature_exponent];
        HairGrid { res, cells, cell, margin, exponents, start, hairs }
    }

    /// At texel `p` (in [0, res)²) and height `h` in [0, 1]: `Ok(())` when inside a hair, else
    /// `Err(d)` with `d` a lower bound of the distance to every hair, in texels (lateral and, for
    /// hairs cut below `h`, vertical with `height_texels` texels per unit of height).
    fn probe(&self, p: Vec2, h: f32, height_texels: f32) -> Result<(), f32> {
        let cx = ((p.x / self.cell) as usize).min(self.cells - 1);
        let cy = ((p.y / self.cell) as usize).min(self.cells - 1);
        let c = cy * self.cells + cx;
        let hn = [h.powf(self.exponents[0]), h.powf(self.exponents[1])];
        let mut bound = self.margin;
        for hair in &self.hairs[self.start[c] as usize..self.start[c + 1] as usize] {
            let top = h.min(hair.length);
            let centre = hair.root
                + hair.bend
                    * if h <= hair.length {
                        hn[hair.coat as usize]
                    } else {
                        top.powf(self.exponents[hair.coat as usize])
                    };
            let mut d = centre - p;
            d.x -= self.res * (d.x / self.res).round();
            d.y -= self.res * (d.y / self.res).round();
            let radius = hair.radius - hair.taper_per_h * top;
            let lateral = d.length() - radius;
            if h <= hair.length {
                if lateral < 0.0 {
                    return Ok(());
                }
                bound = bound.min(lateral);
            } else {
                bound = bound.min(lateral.max((h - hair.length) * height_texels));
            }
        }
        Err(bound)
    }
}

/// One triangle of the skin and, when furry, the prism of fur above it.
#[derive(Clone, Copy, Debug)]
struct Prism {
    p: [Vec3; 3],
    n: [Vec3; 3],
    /// Corner UVs in texels of the tile (`uv · res`).
    uv: [Vec2; 3],
    colour: [Vec3; 3],
    furry: bool,
    /// Inside when `dot(plane.xyz, x) + plane.w ≥ 0` for all five: skin, outermost shell, and the
    /// three sides (each through an edge and its ends' mean normal, shared by the neighbour).
    planes: [Vec4; 5],
    lo: Vec3,
    hi: Vec3,
}

fn plane_through(normal: Vec3, point: Vec3) -> Vec4 {
    let n = normal.normalize_or_zero();
    n.extend(-n.dot(point))
}

impl Prism {
    fn new(p: [Vec3; 3], n: [Vec3; 3], uv: [Vec2; 3], colour: [Vec3; 3], furry: bool, fur_m: f32) -> Prism {
        let mean_n = n[0] + n[1] + n[2];
        let mut face = (p[1] - p[0]).cross(p[2] - p[0]);
        if face.dot(mean_n) < 0.0 {
            face = -face;
        }
        let q = [0, 1, 2].map(|i| p[i] + n[i] * fur_m);
        let mut top = (q[1] - q[0]).cross(q[2] - q[0]);
        if top.dot(mean_n) < 0.0 {
            top = -top;
        }
        let mut planes = [plane_through(face, p[0]), plane_through(-top, q[0]), Vec4::ZERO, Vec4::ZERO, Vec4::ZERO];
        for (k, (a, b, c)) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)].into_iter().enumerate() {
            let mut side = (p[b] - p[a]).cross(n[a] + n[b]);
            if side.dot(p[c] - p[a]) < 0.0 {
                side = -side;
            }
            planes[2 + k] = plane_through(side, p[a]);
        }
        let pad = Vec3::splat(1e-4 + 0.05 * fur_m);
        let (mut lo, mut hi) = (p[0], p[0]);
        for x in p.iter().chain(if furry { q.iter() } else { [].iter() }) {
            lo = lo.min(*x);
            hi = hi.max(*x);
        }
        let (lo, hi) = if furry { (lo - pad, hi + pad) } else { (lo - Vec3::splat(1e-5), hi + Vec3::splat(1e-5)) };
        Prism { p, n, uv, colour, furry, planes, lo, hi }
    }

    /// The ray's parameter interval inside the (plane-bounded) prism, if any.
    fn clip(&self, o: Vec3, d: Vec3, mut s0: f32, mut s1: f32) -> Option<(f32, f32)> {
        for pl in &self.planes {
            let (n, w) = (pl.truncate(), pl.w);
            let (f0, df) = (n.dot(o) + w, n.dot(d));
            if df.abs() < 1e-12 {
                if f0 < 0.0 {
                    return None;
                }
                continue;
            }
            let s = -f0 / df;
            if df > 0.0 {
                s0 = s0.max(s);
            } else {
                s1 = s1.min(s);
            }
            if s0 >= s1 {
                return None;
            }
        }
        Some((s0, s1))
    }

    /// (barycentrics, relative height) of point `x`: the shell triangle `p_i + t·L·n_i` whose
    /// plane holds `x`, found by fixed-point steps (exact in one for equal normals).
    fn locate(&self, x: Vec3, fur_m: f32) -> ([f32; 3], f32) {
        let mut t = 0.0f32;
        let mut b = [1.0 / 3.0; 3];
        for _ in 0..3 {
            let q = [0, 1, 2].map(|i| self.p[i] + self.n[i] * (t * fur_m));
            (b, t) = {
                let (e1, e2) = (q[1] - q[0], q[2] - q[0]);
                let f = e1.cross(e2);
                let area2 = f.length_squared().max(1e-30);
                let r = x - q[0];
                let b1 = r.cross(e2).dot(f) / area2;
                let b2 = e1.cross(r).dot(f) / area2;
                let bary = [1.0 - b1 - b2, b1, b2];
                let fu = f / area2.sqrt();
                let nb = self.n[0] * bary[0] + self.n[1] * bary[1] + self.n[2] * bary[2];
                let rise = (nb.dot(fu) * fur_m).abs().max(1e-12) * nb.dot(fu).signum();
                (bary, t + r.dot(fu) / rise)
            };
        }
        let b = b.map(|v| v.max(0.0));
        let sum = (b[0] + b[1] + b[2]).max(1e-12);
        ([b[0] / sum, b[1] / sum, b[2] / sum], t.clamp(0.0, 1.0))
    }

    fn blend<T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T> + Copy>(v: &[T; 3], b: [f32; 3]) -> T {
        v[0] * b[0] + v[1] * b[1] + v[2] * b[2]
    }
}

/// A bounding-volume hierarchy over the prisms (median split on the longest axis).
struct Bvh {
    /// (lo, hi, first, count): a leaf when `count > 0` (prims `order[first..first+count]`), else
    /// children at `first` and `first + 1`.
    nodes: Vec<(Vec3, Vec3, u32, u32)>,
    order: Vec<u32>,
}

impl Bvh {
    fn new(prisms: &[Prism]) -> Bvh {
        let mut bvh = Bvh { nodes: vec![(Vec3::ZERO, Vec3::ZERO, 0, 0)], order: (0..prisms.len() as u32).collect() };
        bvh.split(prisms, 0, 0, prisms.len());
        bvh
    }

    fn split(&mut self, prisms: &[Prism], node: usize, first: usize, count: usize) {
        let items = &mut self.order[first..first + count];
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for &i in items.iter() {
            lo = lo.min(prisms[i as usize].lo);
            hi = hi.max(prisms[i as usize].hi);
        }
        if count <= 4 {
            self.nodes[node] = (lo, hi, first as u32, count as u32);
            return;
        }
        let ext = hi - lo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let key = |i: &u32| {
            let p = &prisms[*i as usize];
            (p.lo + p.hi)[axis]
        };
        items.sort_unstable_by(|a, b| key(a).total_cmp(&key(b)));
        let child = self.nodes.len();
        self.nodes.push((Vec3::ZERO, Vec3::ZERO, 0, 0));
        self.nodes.push((Vec3::ZERO, Vec3::ZERO, 0, 0));
        self.nodes[node] = (lo, hi, child as u32, 0);
        let half = count / 2;
        self.split(prisms, child, first, half);
        self.split(prisms, child + 1, first + half, count - half);
    }

    /// Every prim whose box the ray (`inv` = 1/d) crosses within [0, s_max], with its entry.
    fn candidates(&self, o: Vec3, inv: Vec3, s_max: f32, out: &mut Vec<u32>) {
        out.clear();
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (lo, hi, first, count) = self.nodes[stack[top] as usize];
            let (a, b) = ((lo - o) * inv, (hi - o) * inv);
            let (near, far) = (a.min(b).max_element().max(0.0), a.max(b).min_element().min(s_max));
            if near > far {
                continue;
            }
            if count > 0 {
                out.extend_from_slice(&self.order[first as usize..(first + count) as usize]);
            } else if top + 2 <= stack.len() {
                stack[top] = first;
                stack[top + 1] = first + 1;
                top += 2;
            }
        }
    }
}

/// The baked hair volume on its mesh, ready to be traced: prisms, their hierarchy and the hair
/// grid of the tile. Built from the pack's sections; the hairs are regrown from the atlas's
/// parameters and seed with the bake's own [`grow_hairs`] (the atlas records the volume seed),
/// so they are the hairs the atlas was sliced from (`tests/rendering.rs` re-slices them and
/// compares the bytes).
pub struct HairVolume {
    prisms: Vec<Prism>,
    bvh: Bvh,
    grid: Arc<HairGrid>,
    fur_m: f32,
    /// Metres of surface per texel of the tile.
    texel_m: f32,
    res: u32,
    shadow: Vec<f32>,
    hairs: HairSet,
}

impl HairVolume {
    /// The volume of a baked pack's skin, shell atlas and UV map.
    pub fn new(mesh: &SkinMesh, atlas: &ShellAtlas, uv_map: &TriangleUvMap) -> Result<HairVolume, ReferenceError> {
        let (v, f) = (mesh.positions.len(), mesh.triangles.len());
        if mesh.normals.len() != v || mesh.colors.len() != v || mesh.fur_mask.len() != f || uv_map.corners.len() != f {
            return Err(ReferenceError::Sections(format!(
                "{v} positions, {} normals, {} colours; {f} triangles, {} fur flags, {} UV triples",
                mesh.normals.len(),
                mesh.colors.len(),
                mesh.fur_mask.len(),
                uv_map.corners.len()
            )));
        }
        if mesh.triangles.iter().flatten().any(|&i| i as usize >= v) {
            return Err(ReferenceError::Sections("a triangle index is out of range".into()));
        }
        let fur_m = atlas.fur_length_m;
        let res = atlas.params.resolution;
        if !(fur_m.is_finite() && fur_m > 0.0) || res == 0 || atlas.shadow.is_empty() {
            return Err(ReferenceError::Sections(format!("fur length {fur_m} m, resolution {res}")));
        }
        let prisms: Vec<Prism> = (0..f)
            .map(|t| {
                let tri = mesh.triangles[t].map(|i| i as usize);
                Prism::new(
                    tri.map(|i| Vec3::from(mesh.positions[i])),
                    tri.map(|i| Vec3::from(mesh.normals[i]).normalize_or(Vec3::Y)),
                    uv_map.corners[t].map(|c| Vec2::from(c) * res as f32),
                    tri.map(|i| Vec3::from_slice(&mesh.colors[i][..3])),
                    mesh.fur_mask[t] != 0,
                    fur_m,
                )
            })
            .collect();
        let bvh = Bvh::new(&prisms);
        let hairs = grow_hairs(&atlas.params, atlas.seed);
        let grid = Arc::new(HairGrid::new(&hairs));
        Ok(HairVolume {
            prisms,
            bvh,
            grid,
            fur_m,
            texel_m: uv_map.repeat_m / res as f32,
            res,
            shadow: atlas.shadow.clone(),
            hairs,
        })
    }

    /// The hairs of the tile (the bake's [`HairSet`]).
    pub fn hairs(&self) -> &HairSet {
        &self.hairs
    }

    /// Hairs of one coat.
    pub fn hair_count(&self, coat: CoatKind) -> usize {
        self.hairs.count(coat)
    }

    /// The self-shadow factor of the slab holding relative height `h` (1 without `self_shadow`).
    fn shadow_at(&self, h: f32) -> f32 {
        let a = self.shadow.len();
        self.shadow[((h * a as f32) as usize).min(a - 1)]
    }

    /// Traces one ray; `scratch` is the candidate list (reused).
    fn trace(&self, o: Vec3, d: Vec3, scratch: &mut Vec<u32>) -> Option<Hit> {
        let inv = d.recip();
        self.bvh.candidates(o, inv, f32::INFINITY, scratch);
        // The nearest skin triangle (either side).
        let mut best: Option<Hit> = None;
        let mut s_best = f32::INFINITY;
        for &i in scratch.iter() {
            let pr = &self.prisms[i as usize];
            if let Some((s, b)) = ray_triangle(o, d, &pr.p) {
                if s < s_best {
                    s_best = s;
                    best = Some(Hit { prism: i, b, h: 0.0, s, hair: false, cell: [0, 0] });
                }
            }
        }
        // The furry prisms in front of it, nearest entry first.
        let mut slabs: Vec<(f32, f32, u32)> = scratch
            .iter()
            .filter_map(|&i| {
                let pr = &self.prisms[i as usize];
                if !pr.furry {
                    return None;
                }
                pr.clip(o, d, 0.0, s_best).map(|(a, b)| (a, b, i))
            })
            .collect();
        slabs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
        let height_texels = self.fur_m / self.texel_m;
        let res = self.res as f32;
        let min_step = 0.02 * self.texel_m;
        for (s0, s1, i) in slabs {
            if s0 >= s_best {
                break;
            }
            let pr = &self.prisms[i as usize];
            let s_end = s1.min(s_best);
            let mut s = s0;
            for _ in 0..4096 {
                let x = o + d * s;
                let (b, h) = pr.locate(x, self.fur_m);
                let uv = Prism::blend(&pr.uv, b);
                let p = Vec2::new(uv.x.rem_euclid(res), uv.y.rem_euclid(res));
                let p = p.min(Vec2::splat(res - 1e-3));
                match self.grid.probe(p, h, height_texels) {
                    Ok(()) => {
                        s_best = s;
                        let cell = [(p.x as i32).min(self.res as i32 - 1), (p.y as i32).min(self.res as i32 - 1)];
                        best = Some(Hit { prism: i, b, h, s, hair: true, cell });
                        break;
                    }
                    Err(bound) => {
                        // Texels → metres, 0.85 for the hairs' tilt and the shells' stretch.
                        s += (0.85 * bound * self.texel_m).max(min_step);
                        if s >= s_end {
                            break;
                        }
                    }
                }
            }
        }
        best
    }

    fn shade(
        &self,
        hit: &Hit,
        world: Vec3,
        eye_dir: Vec3,
        light: &ShadeSettings,
        tint: Vec3,
        self_shadow: bool,
    ) -> Vec3 {
        let pr = &self.prisms[hit.prism as usize];
        let n = Prism::blend(&pr.n, hit.b).normalize_or(pr.n[0]);
        let albedo = Prism::blend(&pr.colour, hit.b) * tint;
        if hit.hair {
            let direct = if self_shadow { self.shadow_at(hit.h) } else { 1.0 };
            // At rest the hair direction the shells shade along is the normal (`strand_tangent`
            // with s = n).
            light.hair(albedo, n, n, world, eye_dir, hit.h, direct, hit.cell)
        } else {
            let direct = if self_shadow { self.shadow[0] } else { 1.0 };
            light.skin(albedo, n, world, eye_dir, pr.furry, direct)
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Hit {
    prism: u32,
    b: [f32; 3],
    h: f32,
    s: f32,
    hair: bool,
    cell: [i32; 2],
}

/// Möller–Trumbore, both faces: (distance, barycentrics).
fn ray_triangle(o: Vec3, d: Vec3, p: &[Vec3; 3]) -> Option<(f32, [f32; 3])> {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let q = d.cross(e2);
    let det = e1.dot(q);
    if det.abs() < 1e-20 {
        return None;
    }
    let inv = 1.0 / det;
    let r = o - p[0];
    let u = r.dot(q) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let k = r.cross(e1);
    let v = d.dot(k) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let s = e2.dot(k) * inv;
    (s > 0.0).then_some((s, [1.0 - u - v, u, v]))
}

/// How a reference image is made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceSettings {
    /// Samples per pixel along each axis: `k × k` jittered strata per pixel. Default 6 (36).
    pub strata: u32,
    /// Seed of the jitter. Default 1.
    pub seed: u64,
    /// Linear RGB background (the renderer's `RenderSettings::background`).
    pub background: [f32; 3],
    /// Linear RGB multiplier of the vertex colours (`RenderSettings::tint`).
    pub tint: [f32; 3],
    /// The self-shadow table (`RenderSettings::self_shadow`).
    pub self_shadow: bool,
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        ReferenceSettings { strata: 6, seed: 1, background: [0.06, 0.06, 0.07], tint: [1.0; 3], self_shadow: true }
    }
}

/// The camera of a frame: the GPU's world → clip matrix (wgpu clip space, depth in [0, 1]) and the
/// eye; rays go through the pixel's sample from the near to the far plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReferenceCamera {
    /// `View::view_proj(aspect)`.
    pub view_proj: Mat4,
    /// Eye position in metres.
    pub eye: Vec3,
}

/// A reference frame: linear RGB per pixel (mean over its samples), and per pixel the share of
/// samples that hit the mesh (skin or hair) and that hit a hair.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major linear RGB.
    pub rgb: Vec<Vec3>,
    /// Share of samples that hit skin or hair, in [0, 1].
    pub coverage: Vec<f32>,
    /// Share of samples that hit a hair, in [0, 1].
    pub hair_coverage: Vec<f32>,
    /// Samples traced in all.
    pub samples: u64,
}

impl ReferenceImage {
    /// sRGB-encoded 8-bit RGB bytes (what the GPU's `Rgba8UnormSrgb` target stores).
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.rgb.iter().flat_map(|c| c.to_array().map(linear_to_srgb8)).collect()
    }
}

/// Linear [0, 1] → sRGB byte (IEC 61966-2-1), rounded.
pub fn linear_to_srgb8(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// Renders `volume` from `camera` lit by `light`: `strata²` jittered samples per pixel, rows in
/// parallel, each sample's jitter a function of (seed, pixel, sample) only, so the image is the
/// same for any thread count.
pub fn render_reference(
    volume: &HairVolume,
    camera: &ReferenceCamera,
    light: &ShadeSettings,
    width: u32,
    height: u32,
    settings: &ReferenceSettings,
) -> Result<ReferenceImage, ReferenceError> {
    if width == 0 || height == 0 || width > 8192 || height > 8192 {
        return Err(ReferenceError::Parameter(format!("size {width}×{height} (each side in 1..=8192)")));
    }
    if !(1..=64).contains(&settings.strata) {
        return Err(ReferenceError::Parameter(format!("strata {} (1..=64)", settings.strata)));
    }
    let inv = camera.view_proj.inverse();
    if !inv.is_finite() {
        return Err(ReferenceError::Parameter("the view-projection matrix is not invertible".into()));
    }
    let k = settings.strata;
    let per_pixel = (k * k) as f32;
    let (background, tint) = (Vec3::from(settings.background), Vec3::from(settings.tint));
    let rows: Vec<Vec<(Vec3, f32, f32)>> = (0..height)
        .into_par_iter()
        .map(|py| {
            let mut scratch = Vec::with_capacity(64);
            (0..width)
                .map(|px| {
                    let pixel = py as u64 * width as u64 + px as u64;
                    let mut rng = SplitMix64::new(derive_seed(settings.seed, 0x7265_6600, pixel));
                    let (mut sum, mut covered, mut hair) = (Vec3::ZERO, 0u32, 0u32);
                    for j in 0..k {
                        for i in 0..k {
                            let sx = px as f32 + (i as f32 + rng.next_f32()) / k as f32;
                            let sy = py as f32 + (j as f32 + rng.next_f32()) / k as f32;
                            let ndc = Vec2::new(sx / width as f32 * 2.0 - 1.0, 1.0 - sy / height as f32 * 2.0);
                            let near = inv.project_point3(ndc.extend(0.0));
                            let far = inv.project_point3(ndc.extend(1.0));
                            let d = (far - near).normalize();
                            match volume.trace(near, d, &mut scratch) {
                                Some(hit) => {
                                    covered += 1;
                                    hair += u32::from(hit.hair);
                                    let x = near + d * hit.s;
                                    let to_eye = (camera.eye - x).normalize_or(-d);
                                    sum += volume.shade(&hit, x, to_eye, light, tint, settings.self_shadow);
                                }
                                None => sum += background,
                            }
                        }
                    }
                    (sum / per_pixel, covered as f32 / per_pixel, hair as f32 / per_pixel)
                })
                .collect()
        })
        .collect();
    let flat: Vec<(Vec3, f32, f32)> = rows.into_iter().flatten().collect();
    Ok(ReferenceImage {
        width,
        height,
        rgb: flat.iter().map(|p| p.0).collect(),
        coverage: flat.iter().map(|p| p.1).collect(),
        hair_coverage: flat.iter().map(|p| p.2).collect(),
        samples: width as u64 * height as u64 * (k * k) as u64,
    })
}

impl HairVolume {
    /// The nearest skin point along a ray from `origin` in direction `dir` (unit), with the
    /// interpolated normal there.
    pub fn skin_point(&self, origin: Vec3, dir: Vec3) -> Option<(Vec3, Vec3)> {
        let mut scratch = Vec::new();
        self.bvh.candidates(origin, dir.recip(), f32::INFINITY, &mut scratch);
        let mut best: Option<(f32, u32, [f32; 3])> = None;
        for &i in &scratch {
            if let Some((s, b)) = ray_triangle(origin, dir, &self.prisms[i as usize].p) {
                if best.is_none_or(|(bs, _, _)| s < bs) {
                    best = Some((s, i, b));
                }
            }
        }
        best.map(|(s, i, b)| {
            let pr = &self.prisms[i as usize];
            (origin + dir * s, Prism::blend(&pr.n, b).normalize_or(pr.n[0]))
        })
    }
}
