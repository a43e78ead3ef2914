//! Keyframe decode and selection — the CPU reference of the blade vertex shader (grass thesis
//! §3.2.5–3.2.6, §4.2): from a blade's horizontal force, take its magnitude and its angle to the
//! blade normal (eq. 3.10–3.12; the sign of the force along the width axis picks the side, so the
//! angle covers the full circle), find the neighbouring poses of the grid, map each to its stored
//! pose and mirror flags (fig. 3.8–3.9: negate x and/or z of the stored vectors), and build the
//! pose: nearest keyframe, linear in-betweening (eq. 3.13, bilinear over magnitude × angle), or
//! spherical (eq. 3.14: the root→vertex vectors are slerped, which keeps the blade's length).
//!
//! Pose keys: magnitude `0` is zero force (the reference, no displacement), `i + 1` is magnitude
//! sample `i`; angles index the full circle, `θ_j = (j + ½)·2π / angles` from the normal (`+z`)
//! towards the width axis (`+x`).

use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::keyframe_table::{Displacements, KeyframeTable, PoseGrid, STATIC_VERTEX, Symmetry};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::GrassError;
use crate::force::ForceField;

/// How a pose is built from the keyframes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PoseInterpolation {
    /// The nearest keyframe (the thesis's choice with 1000 keyframes).
    Nearest,
    /// Linear in-betweening, eq. 3.13, along magnitude and angle.
    Linear,
    /// Spherical in-betweening, eq. 3.14, along angle then magnitude.
    Spherical,
}

impl PoseInterpolation {
    /// Every mode.
    pub const ALL: [PoseInterpolation; 3] =
        [PoseInterpolation::Nearest, PoseInterpolation::Linear, PoseInterpolation::Spherical];

    /// `nearest`, `linear` or `spherical`.
    pub fn name(self) -> &'static str {
        match self {
            PoseInterpolation::Nearest => "nearest",
            PoseInterpolation::Linear => "linear",
            PoseInterpolation::Spherical => "spherical",
        }
    }
}

/// One pose of the represented grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PoseKey {
    /// 0 = zero force, `i + 1` = magnitude sample `i`.
    pub magnitude: u32,
    /// Full-circle angle sample.
    pub angle: u32,
}

/// The poses around a force and their blend: `keys = [(m0, j0), (m0, j1), (m1, j0), (m1, j1)]`,
/// `t_angle` and `t_magnitude` the fractions between them; `weights` the bilinear weights (for
/// [`PoseInterpolation::Nearest`] all four keys are the nearest pose and `weights = [1, 0, 0, 0]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseBlend {
    /// The four neighbouring keys.
    pub keys: [PoseKey; 4],
    /// Bilinear weights of the keys (sum 1).
    pub weights: [f32; 4],
    /// Fraction from angle `j0` to `j1`.
    pub t_angle: f32,
    /// Fraction from magnitude `m0` to `m1`.
    pub t_magnitude: f32,
}

/// A dequantised keyframe table, ready to decode poses.
#[derive(Clone, Debug)]
pub struct KeyframeDecoder {
    grid: PoseGrid,
    symmetry: Symmetry,
    stored_angles: u32,
    stored_vectors: usize,
    vertex_map: Vec<u32>,
    reference: Vec<Vec3>,
    stored: Vec<Vec3>,
    magnitude_per_force: f32,
    angle_per_radian: f32,
}

/// The stored location of a represented pose: stored pose index and mirror flags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoredPose {
    /// Index of the stored pose.
    pub index: u32,
    /// Negate x of the stored vectors.
    pub flip_x: bool,
    /// Negate z of the stored vectors.
    pub flip_z: bool,
}

impl KeyframeDecoder {
    /// Dequantises `table`. The table is trusted to be consistent (it came from `decode` or from
    /// the baker), but counts are re-checked so a hand-built table cannot make lookups panic.
    pub fn new(table: &KeyframeTable) -> Result<Self, GrassError> {
        let values: Vec<f32> = match &table.displacements {
            Displacements::F32(v) => v.clone(),
            Displacements::Snorm16 { scale, values } => values.iter().map(|&q| q as f32 / 32767.0 * scale).collect(),
            Displacements::F16(v) => v.iter().map(|&b| half::f16::from_bits(b).to_f32()).collect(),
            Displacements::Unorm8 { scale, values } => {
                values.iter().map(|&q| (q as f32 * (2.0 / 255.0) - 1.0) * scale).collect()
            }
            Displacements::Snorm8 { scale, values } => values.iter().map(|&q| q as f32 / 127.0 * scale).collect(),
        };
        let sv = table.stored_vectors as usize;
        let g = table.grid;
        let bad = |what: String| GrassError::Format(furbake_formats::FormatError::invalid(what));
        if g.magnitudes == 0 || g.angles == 0 || !g.angles.is_multiple_of(table.symmetry.factor()) {
            return Err(bad(format!("pose grid {g:?} does not fit symmetry {}", table.symmetry.name())));
        }
        let expected = table.stored_poses() as usize * sv * 3;
        if values.len() != expected || table.vertex_map.len() != table.vertex_count() {
            return Err(bad(format!("{} displacement components, expected {expected}", values.len())));
        }
        if table.vertex_map.iter().any(|&m| m != STATIC_VERTEX && m as usize >= sv) {
            return Err(bad("vertex_map points past the stored vectors".into()));
        }
        Ok(KeyframeDecoder {
            grid: g,
            symmetry: table.symmetry,
            stored_angles: g.stored_angles(table.symmetry),
            stored_vectors: sv,
            vertex_map: table.vertex_map.clone(),
            reference: table.reference_positions.iter().map(|p| Vec3::from(*p)).collect(),
            stored: values.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect(),
            magnitude_per_force: g.magnitudes as f32 / g.max_force,
            angle_per_radian: g.angles as f32 / std::f32::consts::TAU,
        })
    }

    /// The pose grid.
    pub fn grid(&self) -> PoseGrid {
        self.grid
    }

    /// Number of vertices of the blade.
    pub fn vertex_count(&self) -> usize {
        self.reference.len()
    }

    /// Reference vertex positions.
    pub fn reference(&self) -> &[Vec3] {
        &self.reference
    }

    /// Where the represented pose `key` is stored (`None` for zero force).
    #[inline]
    pub fn stored_pose(&self, key: PoseKey) -> Option<StoredPose> {
        if key.magnitude == 0 {
            return None;
        }
        let a = self.grid.angles;
        let (mut j, mut flip_x, mut flip_z) = (key.angle, false, false);
        if self.symmetry.mirrors_x() && j >= a / 2 {
            j = a - 1 - j; // θ → −θ
            flip_x = true;
        }
        if self.symmetry.mirrors_z() && j >= a / 4 {
            j = a / 2 - 1 - j; // θ → π − θ
            flip_z = true;
        }
        Some(StoredPose { index: (key.magnitude - 1) * self.stored_angles + j, flip_x, flip_z })
    }

    /// Displacement of vertex `v` in pose `key` (eq. 3.9 with the mirror of fig. 3.8).
    #[inline]
    pub fn displacement(&self, key: PoseKey, v: usize) -> Vec3 {
        let Some(sp) = self.stored_pose(key) else { return Vec3::ZERO };
        let m = self.vertex_map[v];
        if m == STATIC_VERTEX {
            return Vec3::ZERO;
        }
        let d = self.stored[sp.index as usize * self.stored_vectors + m as usize];
        Vec3::new(if sp.flip_x { -d.x } else { d.x }, d.y, if sp.flip_z { -d.z } else { d.z })
    }

    /// Continuous grid coordinates of a blade-local force `(along width axis, along normal)`:
    /// magnitude coordinate in `[0, magnitudes]` and angle coordinate (sample `j` at `j`).
    #[inline]
    pub fn grid_coordinates(&self, force_local: Vec2) -> (f32, f32) {
        let mag = force_local.length();
        let mu = (mag * self.magnitude_per_force).clamp(0.0, self.grid.magnitudes as f32);
        let mut theta = fast_atan2(force_local.x, force_local.y); // eq. 3.12, signed by the width axis
        if theta < 0.0 {
            theta += std::f32::consts::TAU;
        }
        let alpha = theta * self.angle_per_radian - 0.5;
        (mu, alpha)
    }

    /// The poses around a blade-local force `(along width axis, along normal)` and their blend.
    pub fn select(&self, force_local: Vec2, interpolation: PoseInterpolation) -> PoseBlend {
        let (mu, alpha) = self.grid_coordinates(force_local);
        let a = self.grid.angles as i64;
        let wrap = |j: f32| (j as i64).rem_euclid(a) as u32;
        if interpolation == PoseInterpolation::Nearest {
            let key = self.nearest_key(mu, alpha);
            return PoseBlend { keys: [key; 4], weights: [1.0, 0.0, 0.0, 0.0], t_angle: 0.0, t_magnitude: 0.0 };
        }
        let m0 = mu.floor().min(self.grid.magnitudes as f32 - 1.0).max(0.0);
        let tm = (mu - m0).clamp(0.0, 1.0);
        let j0 = alpha.floor();
        let ta = (alpha - j0).clamp(0.0, 1.0);
        let (m0, m1) = (m0 as u32, m0 as u32 + 1);
        let (j0, j1) = (wrap(j0), wrap(j0 + 1.0));
        let key = |magnitude, angle| PoseKey { magnitude, angle };
        PoseBlend {
            keys: [key(m0, j0), key(m0, j1), key(m1, j0), key(m1, j1)],
            weights: [(1.0 - tm) * (1.0 - ta), (1.0 - tm) * ta, tm * (1.0 - ta), tm * ta],
            t_angle: ta,
            t_magnitude: tm,
        }
    }

    /// Blade-local vertex positions of the pose `blend` (reference + displacement; the spherical
    /// mode slerps root→vertex vectors).
    pub fn pose_positions(&self, blend: &PoseBlend, interpolation: PoseInterpolation, out: &mut [Vec3]) {
        for (v, o) in out.iter_mut().enumerate().take(self.reference.len()) {
            let r = self.reference[v];
            *o = match interpolation {
                PoseInterpolation::Nearest => r + self.displacement(blend.keys[0], v),
                PoseInterpolation::Linear => {
                    r + blend.keys.iter().zip(blend.weights).map(|(k, w)| self.displacement(*k, v) * w).sum::<Vec3>()
                }
                PoseInterpolation::Spherical => {
                    let p = blend.keys.map(|k| r + self.displacement(k, v));
                    let lo = slerp(p[0], p[1], blend.t_angle);
                    let hi = slerp(p[2], p[3], blend.t_angle);
                    slerp(lo, hi, blend.t_magnitude)
                }
            };
        }
    }

    /// World-space vertex positions of a blade rooted at `root_m`, turned by `yaw_rad` about `+y`,
    /// scaled by `height_scale` (metres per blade length), under the world horizontal force
    /// `force` (`y` ignored).
    pub fn world_positions(
        &self,
        root_m: Vec3,
        yaw_rad: f32,
        height_scale: f32,
        force: Vec3,
        interpolation: PoseInterpolation,
        out: &mut [Vec3],
    ) {
        let (s, c) = yaw_rad.sin_cos();
        let normal = Vec3::new(s, 0.0, c);
        let width = Vec3::new(c, 0.0, -s);
        let local = Vec2::new(force.dot(width), force.dot(normal));
        let blend = self.select(local, interpolation);
        self.pose_positions(&blend, interpolation, out);
        for p in out.iter_mut().take(self.reference.len()) {
            *p = root_m + (width * p.x + Vec3::Y * p.y + normal * p.z) * height_scale;
        }
    }

    /// The nearest pose packed as the shader receives it: `0` for zero force, else
    /// `(stored pose + 1) << 2 | flip_z << 1 | flip_x`.
    #[inline]
    pub fn nearest_packed(&self, force_local: Vec2) -> u32 {
        // Branch-free (selects only) so the batch loop vectorises; same result as
        // `stored_pose(nearest_key(..))`, which a test checks.
        let (mu, alpha) = self.grid_coordinates(force_local);
        let key = self.nearest_key(mu, alpha);
        let a = self.grid.angles;
        let mut j = key.angle;
        let fx = self.symmetry.mirrors_x() & (j >= a / 2);
        j = if fx { a - 1 - j } else { j };
        let fz = self.symmetry.mirrors_z() & (j >= a / 4);
        j = if fz { a / 2 - 1 - j } else { j };
        let m = key.magnitude;
        let index = m.wrapping_sub(1).wrapping_mul(self.stored_angles).wrapping_add(j + 1);
        let packed = index.wrapping_shl(2) | (fz as u32) << 1 | fx as u32;
        if m == 0 { 0 } else { packed }
    }

    /// The nearest key to grid coordinates `(mu, alpha)` (ties round up).
    #[inline]
    pub fn nearest_key(&self, mu: f32, alpha: f32) -> PoseKey {
        // mu ≥ 0 and alpha ≥ −0.5, so `+ 0.5` then truncation rounds without a libm call;
        // alpha rounds into [0, angles], and `angles` wraps to 0.
        let j = (alpha + 0.5) as u32;
        let j = if j >= self.grid.angles { j - self.grid.angles } else { j };
        PoseKey { magnitude: ((mu + 0.5) as u32).min(self.grid.magnitudes), angle: j }
    }
}

/// `atan2(y, x)` to within 2e-5 rad (a minimax polynomial on `[0, 1]` plus octant folding), the
/// kind of approximation a shader uses; the CPU reference and the batch decode share it.
#[inline]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = if ax < ay { (ax, ay) } else { (ay, ax) };
    if hi == 0.0 {
        return 0.0;
    }
    let a = lo / hi;
    let s = a * a;
    let mut r = ((((0.0208351 * s - 0.085133) * s + 0.180141) * s - 0.3302995) * s + 0.999866) * a;
    if ay > ax {
        r = std::f32::consts::FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = std::f32::consts::PI - r;
    }
    if y < 0.0 { -r } else { r }
}

/// Spherical linear interpolation of two vectors (eq. 3.14); falls back to linear when they are
/// (anti)parallel within 1e-6 or one is zero.
///
/// `a·sin((1−t)ω)/sin ω + b·sin(tω)/sin ω` with `ω` the angle between `a` and `b`, evaluated
/// without libm: `sin ω = √((1−cos ω)(1+cos ω))` (exact for the rounded `cos ω`, where
/// `sin(acos(·))` would cost two calls), `ω` by [`fast_acos`] and the two sines by [`fast_sin`],
/// both polynomials accurate to f32 round-off. The spherical decode calls this three times per
/// vertex; the polynomials take about half the time of libm's `acosf` and three `sinf` (the
/// accuracy report measures both), and are at least as close to an f64 slerp (a test compares
/// both with one).
#[inline]
pub fn slerp(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    let (la2, lb2) = (a.length_squared(), b.length_squared());
    if la2 == 0.0 || lb2 == 0.0 {
        return a.lerp(b, t);
    }
    let cos = (a.dot(b) / (la2 * lb2).sqrt()).clamp(-1.0, 1.0);
    let s = ((1.0 - cos) * (1.0 + cos)).sqrt();
    if s < 1e-6 {
        return a.lerp(b, t);
    }
    let omega = fast_acos(cos);
    let inv = 1.0 / s;
    a * (fast_sin((1.0 - t) * omega) * inv) + b * (fast_sin(t * omega) * inv)
}

/// `acos(x)` for `x` in [−1, 1] to within 5e-7 rad (2 f32 ulps at π) (Abramowitz & Stegun 4.4.46: `√(1−|x|)` times a
/// degree-7 polynomial, mirrored for negative `x`).
#[inline]
pub fn fast_acos(x: f32) -> f32 {
    let ax = x.abs().min(1.0);
    let p = ((((((-0.001_262_491_1 * ax + 0.006_670_09) * ax - 0.017_088_126) * ax + 0.030_891_88) * ax
        - 0.050_174_304)
        * ax
        + 0.088_978_99)
        * ax
        - 0.214_598_8)
        * ax
        + std::f32::consts::FRAC_PI_2; // a₀ = 1.5707963050 rounds to the same f32
    let r = (1.0 - ax).sqrt() * p;
    if x < 0.0 { std::f32::consts::PI - r } else { r }
}

/// `sin(x)` for `x` in [0, π] to within 2e-7 (folded onto [0, π/2], then the Taylor series to x¹³).
#[inline]
pub fn fast_sin(x: f32) -> f32 {
    let x = if x > std::f32::consts::FRAC_PI_2 { std::f32::consts::PI - x } else { x };
    let x2 = x * x;
    let p = 1.0
        + x2 * (-1.0 / 6.0
            + x2 * (1.0 / 120.0
                + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362_880.0 + x2 * (-1.0 / 39_916_800.0 + x2 / 6_227_020_800.0)))));
    x * p
}

/// Blades as the per-frame decode reads them: struct of arrays with the trigonometry and corner
/// indices precomputed.
#[derive(Clone, Debug, Default)]
pub struct BladeSoa {
    /// Root x, metres.
    pub x: Vec<f32>,
    /// Root y, metres.
    pub y: Vec<f32>,
    /// Root z, metres.
    pub z: Vec<f32>,
    /// `cos yaw`.
    pub cos_yaw: Vec<f32>,
    /// `sin yaw`.
    pub sin_yaw: Vec<f32>,
    /// The four cluster corner indices.
    pub corners: Vec<[u32; 4]>,
    /// The four bilinear weights.
    pub weights: Vec<[f32; 4]>,
}

impl BladeSoa {
    /// Unpacks a blade field.
    pub fn from_field(field: &BladeField) -> Self {
        let n = field.blade_count();
        let mut s = BladeSoa {
            x: Vec::with_capacity(n),
            y: Vec::with_capacity(n),
            z: Vec::with_capacity(n),
            cos_yaw: Vec::with_capacity(n),
            sin_yaw: Vec::with_capacity(n),
            corners: Vec::with_capacity(n),
            weights: field.weights.clone(),
        };
        for b in 0..n {
            let p = field.positions[b];
            s.x.push(p[0]);
            s.y.push(p[1]);
            s.z.push(p[2]);
            let (sn, c) = field.yaw_rad[b].sin_cos();
            s.cos_yaw.push(c);
            s.sin_yaw.push(sn);
            s.corners.push(field.grid.corner_indices(field.cluster[b]));
        }
        s
    }

    /// Number of blades.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True when there are no blades.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
}

/// Per-frame CPU decode of every blade: the interpolated force (eq. 3.6, with delayed attenuation
/// when the field has delayed sources), then the nearest pose packed as
/// [`KeyframeDecoder::nearest_packed`]. Parallel, chunked, independent of the thread count.
/// Decodes `min(out.len(), blades.len())` blades; corner indices must lie in `field`'s grid (they
/// do for a [`BladeSoa`] built from the field's own blade field).
pub fn decode_nearest_batch(decoder: &KeyframeDecoder, field: &ForceField, blades: &BladeSoa, out: &mut [u32]) {
    const CHUNK: usize = 4096;
    let n = out.len().min(blades.len());
    out[..n].par_chunks_mut(CHUNK).enumerate().for_each(|(c, chunk)| {
        let base = c * CHUNK;
        let len = chunk.len();
        // Pass 1 gathers the corner forces (eq. 3.6); pass 2 is gather-free and vectorises.
        let mut lx = [0.0f32; CHUNK];
        let mut ly = [0.0f32; CHUNK];
        for i in 0..len {
            let b = base + i;
            let pos = Vec3::new(blades.x[b], blades.y[b], blades.z[b]);
            let f = field.blade_force(blades.corners[b], blades.weights[b], pos);
            let (c, s) = (blades.cos_yaw[b], blades.sin_yaw[b]);
            // width axis (c, −s), normal (s, c) in xz.
            lx[i] = f.x * c - f.y * s;
            ly[i] = f.x * s + f.y * c;
        }
        for i in 0..len {
            chunk[i] = decoder.nearest_packed(Vec2::new(lx[i], ly[i]));
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keyframes::{KeyframeSettings, PoseGridSettings, bake_keyframe_table};
    use furbake_formats::sections::keyframe_table::DisplacementEncoding;

    fn table(symmetry: Symmetry, poses: u32) -> KeyframeTable {
        let s = KeyframeSettings {
            grid: PoseGridSettings { poses, ..Default::default() },
            symmetry,
            encoding: DisplacementEncoding::F32,
            ..KeyframeSettings::thesis()
        };
        bake_keyframe_table(&s).expect("bakes")
    }

    #[test]
    fn packed_nearest_pose_matches_the_reference_selection() {
        let mut checked = 0;
        for sym in [Symmetry::None, Symmetry::X, Symmetry::XZ] {
            let d = KeyframeDecoder::new(&table(sym, 400)).expect("decoder");
            for k in 0..2000 {
                let theta = k as f32 * 0.0131 - 3.0;
                let force = Vec2::new(theta.sin(), theta.cos()) * (k % 50) as f32 * 0.1;
                let key = d.select(force, PoseInterpolation::Nearest).keys[0];
                let expect = match d.stored_pose(key) {
                    None => 0,
                    Some(sp) => (sp.index + 1) << 2 | (sp.flip_z as u32) << 1 | sp.flip_x as u32,
                };
                assert_eq!(d.nearest_packed(force), expect, "{sym:?} force {force}");
                checked += 1;
            }
        }
        assert_eq!(checked, 6000);
    }

    #[test]
    fn fast_atan2_is_within_its_bound() {
        let mut worst = 0.0f32;
        let mut n = 0;
        for k in 0..3600 {
            let t = k as f32 * 0.1f32.to_radians() - std::f32::consts::PI + 1e-4;
            for r in [1e-3f32, 1.0, 250.0] {
                let (y, x) = (r * t.sin(), r * t.cos());
                worst = worst.max((fast_atan2(y, x) - y.atan2(x)).abs());
                n += 1;
            }
        }
        assert_eq!(n, 10_800);
        assert!(worst < 2e-5, "worst error {worst}");
        assert_eq!(fast_atan2(0.0, 1.0), 0.0);
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
    }

    #[test]
    fn blade_turned_half_a_turn_under_the_opposite_force_is_the_mirror_image() {
        // Same force relative to the blade ⇒ same local pose; in the world the two poses are each
        // other's image under the half turn about the root (x → −x, z → −z).
        let d = KeyframeDecoder::new(&table(Symmetry::XZ, 1000)).expect("decoder");
        let root = Vec3::new(1.0, 0.5, -2.0);
        let mut checked = 0;
        for (yaw, force) in
            [(0.3f32, Vec3::new(1.2, 0.0, 2.1)), (2.0, Vec3::new(-3.0, 0.0, 0.4)), (-1.0, Vec3::new(0.1, 0.0, -0.9))]
        {
            for mode in PoseInterpolation::ALL {
                let mut a = vec![Vec3::ZERO; 32];
                let mut b = vec![Vec3::ZERO; 32];
                d.world_positions(root, yaw, 0.3, force, mode, &mut a);
                d.world_positions(root, yaw + std::f32::consts::PI, 0.3, -force, mode, &mut b);
                for v in 0..32 {
                    let (pa, pb) = (a[v] - root, b[v] - root);
                    let mirrored = Vec3::new(-pb.x, pb.y, -pb.z);
                    assert!((pa - mirrored).length() < 1e-5, "{mode:?} vertex {v}: {pa} vs {mirrored}");
                    checked += 1;
                }
                let tip_shift = a[30] - (root + Vec3::Y * 0.3);
                assert!(tip_shift.dot(force) > 0.0, "{mode:?}: the tip moves with the force");
            }
        }
        assert_eq!(checked, 3 * 3 * 32);
    }

    #[test]
    fn symmetric_and_full_tables_decode_the_same_pose() {
        let full = KeyframeDecoder::new(&table(Symmetry::None, 400)).expect("decoder");
        let mut checked = 0;
        for sym in [Symmetry::X, Symmetry::XZ] {
            let half = KeyframeDecoder::new(&table(sym, 400)).expect("decoder");
            for k in 0..40 {
                let theta = k as f32 * 0.161;
                let force = Vec2::new(theta.sin(), theta.cos()) * (0.1 * k as f32);
                for mode in PoseInterpolation::ALL {
                    let (mut a, mut b) = (vec![Vec3::ZERO; 32], vec![Vec3::ZERO; 32]);
                    full.pose_positions(&full.select(force, mode), mode, &mut a);
                    half.pose_positions(&half.select(force, mode), mode, &mut b);
                    for v in 0..32 {
                        assert!((a[v] - b[v]).length() < 1e-5, "{sym:?} {mode:?} k {k} v {v}");
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 2 * 40 * 3 * 32);
    }

    /// The polynomial slerp agrees with an f64 slerp at least as closely as libm's f32 functions did, and
    /// its building blocks are accurate over their whole domain.
    #[test]
    fn fast_slerp_matches_an_f64_slerp() {
        fn slerp64(a: Vec3, b: Vec3, t: f64) -> glam::DVec3 {
            let (a, b) = (a.as_dvec3(), b.as_dvec3());
            let cos = (a.dot(b) / (a.length() * b.length())).clamp(-1.0, 1.0);
            let w = cos.acos();
            (a * ((1.0 - t) * w).sin() + b * (t * w).sin()) / w.sin()
        }
        fn slerp_libm(a: Vec3, b: Vec3, t: f32) -> Vec3 {
            let (la, lb) = (a.length(), b.length());
            let cos = (a.dot(b) / (la * lb)).clamp(-1.0, 1.0);
            let omega = cos.acos();
            let s = omega.sin();
            a * (((1.0 - t) * omega).sin() / s) + b * ((t * omega).sin() / s)
        }
        let mut rng = crate::rng::SplitMix64::new(7);
        let mut v = || Vec3::new(rng.next_f32() - 0.5, rng.next_f32(), rng.next_f32() - 0.5);
        let (mut worst_fast, mut worst_libm) = (0.0f64, 0.0f64);
        for i in 0..20_000 {
            let a = v();
            // Near neighbours (small angles, as adjacent keyframes) and arbitrary pairs.
            let b = if i % 2 == 0 { a + 0.01 * v() } else { v() };
            let t = (i % 11) as f32 / 10.0;
            let exact = slerp64(a, b, t as f64);
            if !exact.is_finite() || a.angle_between(b) < 1e-3 {
                continue;
            }
            let scale = exact.length().max(1e-3);
            worst_fast = worst_fast.max((slerp(a, b, t).as_dvec3() - exact).length() / scale);
            worst_libm = worst_libm.max((slerp_libm(a, b, t).as_dvec3() - exact).length() / scale);
        }
        // Small angles are ill-conditioned in f32 for both (cos ω rounds); the polynomial version,
        // with sin ω = √((1−c)(1+c)), is never further from the f64 slerp than libm's.
        assert!(worst_fast < 1e-3 && worst_fast <= worst_libm, "{worst_fast:e} vs libm {worst_libm:e}");
        for i in 0..=2000 {
            let x = -1.0 + i as f32 / 1000.0;
            assert!((fast_acos(x) as f64 - (x as f64).acos()).abs() < 5e-7, "acos {x}"); // 2 ulps at π
            let y = std::f32::consts::PI * i as f32 / 2000.0;
            assert!((fast_sin(y) as f64 - (y as f64).sin()).abs() < 3e-7, "sin {y}");
        }
        // Parallel and zero vectors fall back to lerp.
        assert_eq!(slerp(Vec3::X, Vec3::X * 2.0, 0.5), Vec3::X * 1.5);
        assert_eq!(slerp(Vec3::ZERO, Vec3::Y, 0.25), Vec3::Y * 0.25);
    }

    #[test]
    fn interpolation_hits_keyframes_and_slerp_keeps_the_blade_length() {
        let t = table(Symmetry::XZ, 100);
        let d = KeyframeDecoder::new(&t).expect("decoder");
        let g = d.grid();
        // At a grid force every mode returns that keyframe.
        let (m, j) = (2u32, 7u32);
        let theta = g.angle(j);
        let force = Vec2::new(theta.sin(), theta.cos()) * g.magnitude(m);
        let key = PoseKey { magnitude: m + 1, angle: j };
        for mode in PoseInterpolation::ALL {
            let blend = d.select(force, mode);
            let mut p = vec![Vec3::ZERO; 32];
            d.pose_positions(&blend, mode, &mut p);
            for (v, pv) in p.iter().enumerate() {
                assert!((*pv - d.reference()[v] - d.displacement(key, v)).length() < 1e-4, "{mode:?} v {v}");
            }
        }
        // Half way between two angles, slerp keeps the root→tip distance better than lerp.
        let mid = 0.5 * (g.angle(j) + g.angle(j + 1));
        let force = Vec2::new(mid.sin(), mid.cos()) * g.max_force;
        let tip = |mode| {
            let mut p = vec![Vec3::ZERO; 32];
            d.pose_positions(&d.select(force, mode), mode, &mut p);
            p[30].length()
        };
        let keyed =
            |angle| (d.reference()[30] + d.displacement(PoseKey { magnitude: g.magnitudes, angle }, 30)).length();
        let mean = 0.5 * (keyed(j) + keyed(j + 1));
        let (lin, sph) = (tip(PoseInterpolation::Linear), tip(PoseInterpolation::Spherical));
        assert!((sph - mean).abs() < 2e-3, "slerp keeps the length: {sph} vs {mean}");
        assert!((lin - mean).abs() > 2.0 * (sph - mean).abs(), "lerp shortens the blade: {lin} vs {sph} ({mean})");
        // Zero force: the reference blade.
        let mut p = vec![Vec3::ONE; 32];
        d.pose_positions(&d.select(Vec2::ZERO, PoseInterpolation::Nearest), PoseInterpolation::Nearest, &mut p);
        assert_eq!(p, d.reference());
        assert_eq!(d.nearest_packed(Vec2::ZERO), 0);
    }
}
