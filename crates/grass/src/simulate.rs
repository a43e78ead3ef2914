//! The physical blade model that generates the keyframes (grass thesis §3.2.4, §3.3): the centre
//! line is a chain of rigid, length-preserving segments (§3.3: "each grass segment is a rigid
//! body") joined by bending springs, clamped at the root, loaded by gravity and by a horizontal
//! external force spread over the blade in proportion to its area, and settled to static
//! equilibrium.
//!
//! Each segment's direction is written as a *tilt* `a = (a_x, a_z)`: the segment leans by the
//! angle `|a|` towards the horizontal direction `(a_x, 0, a_z)/|a|`. The bend at a joint is the
//! difference of the tilts of the segments it joins (minus the rest bend); a flat blade is far
//! stiffer in its own plane (bending towards ±x) than across it (towards ±z, the normal), so the
//! two components have different stiffnesses (second moment of area `w t³` vs `t w³`), scaled by
//! the local width. The blade does not twist: each quad edge is translated with its centre-line
//! node, which is what lets one vector serve a rigid segment pair (thesis fig. 3.7).
//!
//! The equilibrium is the minimum of `E = Σ ½ rᵀK r − Σ Gᵢ·pᵢ`, found by damped Newton
//! (Levenberg–Marquardt) with the exact gradient and a central-difference Hessian, in `f64`.
//! Everything is mirror-equivariant: a force mirrored in `x = 0` (or `z = 0`, for a straight
//! blade) gives the mirrored pose.

use glam::{DVec2, DVec3};

use crate::GrassError;
use crate::blade::ReferenceBlade;

/// Material of the simulated blade. Units: a blade one length unit long (the keyframes are in
/// blade lengths), forces in the same unit as [`crate::PoseGridSettings::max_force`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct BladeMaterial {
    /// Bending stiffness `EI` across the blade (bending towards its normal) at the root, force ×
    /// length². Default 1.0. Scaled along the blade by the local width.
    pub bending_stiffness: f64,
    /// In-plane (towards ±x) over out-of-plane (towards ±z) stiffness. Default 20.
    pub width_stiffness_ratio: f64,
    /// Total weight of the blade (force; pulls towards −y). Default 0.05.
    pub weight: f64,
}

impl Default for BladeMaterial {
    fn default() -> Self {
        BladeMaterial { bending_stiffness: 1.0, width_stiffness_ratio: 20.0, weight: 0.05 }
    }
}

/// A settled blade.
#[derive(Clone, Debug, PartialEq)]
pub struct Equilibrium {
    /// Tilt of each segment (`x`, `z` components).
    pub tilts: Vec<DVec2>,
    /// Centre-line node positions (`S + 1`, root first).
    pub nodes: Vec<DVec3>,
    /// Newton iterations used.
    pub iterations: u32,
    /// Largest gradient component at the end (force × length).
    pub gradient_norm: f64,
}

/// The discretised blade, ready to settle under any horizontal force.
#[derive(Clone, Debug)]
pub struct BladeSimulator {
    lengths: Vec<f64>,
    rest_tilt: Vec<DVec2>,
    stiffness: Vec<DVec2>,
    load_share: Vec<f64>,
    weight: f64,
}

/// Newton iterations before giving up.
const MAX_ITERATIONS: u32 = 200;
/// Converged when every gradient component is below this (force × length).
const GRADIENT_TOLERANCE: f64 = 1e-11;

fn direction(a: DVec2) -> DVec3 {
    let t2 = a.length_squared();
    let t = t2.sqrt();
    let s = if t < 1e-4 { 1.0 - t2 / 6.0 } else { t.sin() / t };
    DVec3::new(s * a.x, t.cos(), s * a.y)
}

/// `∂d/∂a` transposed applied to `v`: returns `(v·∂d/∂a_x, v·∂d/∂a_z)`.
fn direction_jt(a: DVec2, v: DVec3) -> DVec2 {
    let t2 = a.length_squared();
    let t = t2.sqrt();
    let (s, c) = if t < 1e-4 {
        (1.0 - t2 / 6.0, -1.0 / 3.0 + t2 / 30.0)
    } else {
        (t.sin() / t, (t * t.cos() - t.sin()) / (t2 * t))
    };
    let dx = DVec3::new(s + c * a.x * a.x, -s * a.x, c * a.x * a.y);
    let dz = DVec3::new(c * a.x * a.y, -s * a.y, s + c * a.y * a.y);
    DVec2::new(v.dot(dx), v.dot(dz))
}

impl BladeSimulator {
    /// Discretises `blade` with `material`.
    pub fn new(blade: &ReferenceBlade, material: &BladeMaterial) -> Result<Self, GrassError> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !ok(material.bending_stiffness) || !ok(material.width_stiffness_ratio) {
            return Err(GrassError::parameter(format!("blade material {material:?}: stiffnesses must be positive")));
        }
        if !(material.weight.is_finite() && material.weight >= 0.0) {
            return Err(GrassError::parameter(format!("blade weight {} must be ≥ 0", material.weight)));
        }
        let s = blade.segments as usize;
        let mut lengths = Vec::with_capacity(s);
        let mut rest_tilt = Vec::with_capacity(s);
        let mut stiffness = Vec::with_capacity(s);
        let mut load_share = vec![0.0; s + 1];
        for k in 0..s {
            let d = blade.nodes[k + 1] - blade.nodes[k];
            let l = d.length();
            let u = d / l;
            let horiz = DVec2::new(u.x, u.z);
            let theta = u.y.clamp(-1.0, 1.0).acos();
            rest_tilt.push(if horiz.length() > 0.0 { horiz.normalize() * theta } else { DVec2::ZERO });
            lengths.push(l);
            let ei = material.bending_stiffness * blade.widths[k] / blade.widths[0];
            let kz = ei / l;
            stiffness.push(DVec2::new(kz * material.width_stiffness_ratio, kz));
            let area = l * 0.5 * (blade.widths[k] + blade.widths[k + 1]);
            load_share[k] += 0.5 * area;
            load_share[k + 1] += 0.5 * area;
        }
        load_share[0] = 0.0; // the root is clamped: its share goes to the ground
        let total: f64 = load_share.iter().sum();
        load_share.iter_mut().for_each(|w| *w /= total);
        Ok(BladeSimulator { lengths, rest_tilt, stiffness, load_share, weight: material.weight })
    }

    /// Number of segments.
    pub fn segments(&self) -> usize {
        self.lengths.len()
    }

    /// Node positions for the given tilts.
    pub fn nodes(&self, tilts: &[DVec2]) -> Vec<DVec3> {
        let mut p = DVec3::ZERO;
        let mut out = Vec::with_capacity(tilts.len() + 1);
        out.push(p);
        for (a, l) in tilts.iter().zip(&self.lengths) {
            p += direction(*a) * *l;
            out.push(p);
        }
        out
    }

    fn node_load(&self, force: DVec3, i: usize) -> DVec3 {
        let w = self.load_share[i];
        DVec3::new(force.x * w, -self.weight * w, force.z * w)
    }

    fn energy(&self, force: DVec3, tilts: &[DVec2]) -> f64 {
        let mut e = 0.0;
        let mut prev = DVec2::ZERO;
        for (k, a) in tilts.iter().enumerate() {
            let b = *a - self.rest_tilt[k];
            let r = b - prev;
            e += 0.5 * (self.stiffness[k] * r * r).element_sum();
            prev = b;
        }
        let nodes = self.nodes(tilts);
        for (i, p) in nodes.iter().enumerate().skip(1) {
            e -= self.node_load(force, i).dot(*p);
        }
        e
    }

    fn gradient(&self, force: DVec3, tilts: &[DVec2], out: &mut [DVec2]) {
        let s = tilts.len();
        // Bending: ∂/∂a_k of Σ ½ rᵀKr with r_k = b_k − b_{k−1}.
        let mut r = vec![DVec2::ZERO; s + 1];
        let mut prev = DVec2::ZERO;
        for k in 0..s {
            let b = tilts[k] - self.rest_tilt[k];
            r[k] = self.stiffness[k] * (b - prev);
            prev = b;
        }
        // Loads: −l_k J_kᵀ Σ_{i>k} G_i, accumulated from the tip.
        let mut beyond = DVec3::ZERO;
        for k in (0..s).rev() {
            beyond += self.node_load(force, k + 1);
            let load = -direction_jt(tilts[k], beyond) * self.lengths[k];
            out[k] = r[k] - r[k + 1] + load;
        }
    }

    /// Settles the blade under the horizontal `force` (blade-local; its `y` is ignored), starting
    /// from `warm` tilts when given (e.g. the previous magnitude's solution).
    pub fn settle(&self, force: DVec3, warm: Option<&[DVec2]>) -> Result<Equilibrium, GrassError> {
        let force = DVec3::new(force.x, 0.0, force.z);
        if !force.is_finite() {
            return Err(GrassError::parameter(format!("force {force} is not finite")));
        }
        let s = self.segments();
        let n = 2 * s;
        let mut x: Vec<DVec2> = match warm {
            Some(w) if w.len() == s => w.to_vec(),
            _ => self.rest_tilt.clone(),
        };
        let mut g = vec![DVec2::ZERO; s];
        let mut gp = vec![DVec2::ZERO; s];
        let mut gm = vec![DVec2::ZERO; s];
        let mut h = vec![0.0f64; n * n];
        let mut lambda = 1e-6;
        let mut e = self.energy(force, &x);
        for it in 0..MAX_ITERATIONS {
            self.gradient(force, &x, &mut g);
            let gnorm = g.iter().map(|v| v.abs().max_element()).fold(0.0, f64::max);
            if gnorm < GRADIENT_TOLERANCE {
                return Ok(Equilibrium { nodes: self.nodes(&x), tilts: x, iterations: it, gradient_norm: gnorm });
            }
            // Central-difference Hessian of the exact gradient.
            const H: f64 = 1e-6;
            for col in 0..n {
                let (k, c) = (col / 2, col % 2);
                let orig = x[k];
                x[k][c] = orig[c] + H;
                self.gradient(force, &x, &mut gp);
                x[k][c] = orig[c] - H;
                self.gradient(force, &x, &mut gm);
                x[k] = orig;
                for row in 0..n {
                    h[row * n + col] = (gp[row / 2][row % 2] - gm[row / 2][row % 2]) / (2.0 * H);
                }
            }
            for row in 0..n {
                for col in 0..row {
                    let avg = 0.5 * (h[row * n + col] + h[col * n + row]);
                    h[row * n + col] = avg;
                    h[col * n + row] = avg;
                }
            }
            let rhs: Vec<f64> = g.iter().flat_map(|v| [-v.x, -v.y]).collect();
            let mut accepted = false;
            for _ in 0..60 {
                if let Some(step) = solve_damped(&h, n, lambda, &rhs) {
                    let trial: Vec<DVec2> =
                        x.iter().enumerate().map(|(k, a)| *a + DVec2::new(step[2 * k], step[2 * k + 1])).collect();
                    let et = self.energy(force, &trial);
                    if et.is_finite() && et <= e + 1e-14 * e.abs().max(1.0) {
                        x = trial;
                        e = et;
                        lambda = (lambda / 4.0).max(1e-12);
                        accepted = true;
                        break;
                    }
                }
                lambda *= 8.0;
            }
            if !accepted {
                // No descent step exists at this precision: the gradient is as small as f64 allows.
                return Ok(Equilibrium { nodes: self.nodes(&x), tilts: x, iterations: it, gradient_norm: gnorm });
            }
        }
        self.gradient(force, &x, &mut g);
        let gnorm = g.iter().map(|v| v.abs().max_element()).fold(0.0, f64::max);
        if gnorm < 1e-7 {
            return Ok(Equilibrium {
                nodes: self.nodes(&x),
                tilts: x,
                iterations: MAX_ITERATIONS,
                gradient_norm: gnorm,
            });
        }
        Err(GrassError::NotConverged { force: [force.x, force.z], gradient: gnorm })
    }
}

/// Solves `(H + λI) x = b` by Cholesky; `None` when the damped matrix is not positive definite.
fn solve_damped(h: &[f64], n: usize, lambda: f64, b: &[f64]) -> Option<Vec<f64>> {
    let mut l = vec![0.0f64; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut sum = h[i * n + j] + if i == j { lambda } else { 0.0 };
            for k in 0..j {
                sum -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if sum <= 0.0 || !sum.is_finite() {
                    return None;
                }
                l[i * n + i] = sum.sqrt();
            } else {
                l[i * n + j] = sum / l[j * n + j];
            }
        }
    }
    let mut y = vec![0.0f64; n];
    for i in 0..n {
        let mut sum = b[i];
        for k in 0..i {
            sum -= l[i * n + k] * y[k];
        }
        y[i] = sum / l[i * n + i];
    }
    let mut x = vec![0.0f64; n];
    for i in (0..n).rev() {
        let mut sum = y[i];
        for k in i + 1..n {
            sum -= l[k * n + i] * x[k];
        }
        x[i] = sum / l[i * n + i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blade::{BladeShape, build_reference_blade};

    fn sim() -> BladeSimulator {
        let blade = build_reference_blade(&BladeShape::default()).expect("default blade");
        BladeSimulator::new(&blade, &BladeMaterial::default()).expect("default material")
    }

    #[test]
    fn gradient_matches_finite_differences_of_the_energy() {
        let s = sim();
        let tilts: Vec<DVec2> = (0..8).map(|k| DVec2::new(0.05 * k as f64, -0.1 + 0.03 * k as f64)).collect();
        let force = DVec3::new(0.7, 0.0, -1.3);
        let mut g = vec![DVec2::ZERO; 8];
        s.gradient(force, &tilts, &mut g);
        let mut checked = 0;
        for k in 0..8 {
            for c in 0..2 {
                let mut p = tilts.clone();
                p[k][c] += 1e-6;
                let mut m = tilts.clone();
                m[k][c] -= 1e-6;
                let fd = (s.energy(force, &p) - s.energy(force, &m)) / 2e-6;
                assert!((fd - g[k][c]).abs() < 1e-6, "component {k}.{c}: {fd} vs {}", g[k][c]);
                checked += 1;
            }
        }
        assert_eq!(checked, 16);
    }

    #[test]
    fn segments_keep_their_length_and_the_blade_bends_with_the_force() {
        let s = sim();
        let eq = s.settle(DVec3::new(0.0, 0.0, 3.0), None).expect("converges");
        assert!(eq.gradient_norm < 1e-9);
        for w in eq.nodes.windows(2) {
            assert!(((w[1] - w[0]).length() - 0.125).abs() < 1e-12, "rigid segments keep their length");
        }
        let tip = eq.nodes[8];
        assert!(tip.z > 0.2, "tip bends along +z: {tip}");
        assert!(tip.x.abs() < 1e-12, "no sideways motion under a normal force");
        assert!(tip.y < 1.0);
        // Sideways (in-plane) bending is stiffer than bending towards the normal.
        let side = s.settle(DVec3::new(3.0, 0.0, 0.0), None).expect("converges");
        assert!(side.nodes[8].x > 0.0 && side.nodes[8].x < tip.z * 0.5, "{} vs {}", side.nodes[8].x, tip.z);
        // Zero force: the blade stays at rest (gravity is too weak to buckle it).
        let rest = s.settle(DVec3::ZERO, None).expect("converges");
        assert!(rest.nodes.iter().all(|p| p.x == 0.0 && p.z == 0.0));
    }

    #[test]
    fn mirrored_forces_give_mirrored_poses() {
        let s = sim();
        let f = DVec3::new(1.1, 0.0, 2.3);
        let a = s.settle(f, None).expect("converges");
        let bx = s.settle(DVec3::new(-f.x, 0.0, f.z), None).expect("converges");
        let bz = s.settle(DVec3::new(f.x, 0.0, -f.z), None).expect("converges");
        for i in 0..9 {
            let (p, qx, qz) = (a.nodes[i], bx.nodes[i], bz.nodes[i]);
            assert!((p - DVec3::new(-qx.x, qx.y, qx.z)).length() < 1e-12);
            assert!((p - DVec3::new(qz.x, qz.y, -qz.z)).length() < 1e-12);
        }
    }
}
