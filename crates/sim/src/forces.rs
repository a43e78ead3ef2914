//! External forces on the free masses (fur thesis §3.4.1, last paragraph; §3.4.3): gravity,
//! global time-varying wind, object motion turned into inertial forces in the mesh frame, local
//! interaction forces (a point with radius and strength) and the restoring force of eq. 3.37,
//! `F = (n − s)(1 − n·s)·w`, on every tip mass.
//!
//! The simulation runs in the mesh (object) frame: anchored masses never move there, and every
//! vector below is expressed in that frame. A moving object is described by the frame's linear
//! acceleration, angular velocity and angular acceleration; a free mass of mass `m` at `r` with
//! velocity `v` then feels `−m (a + α×r + ω×(ω×r) + 2 ω×v)`.

use glam::{DMat3, DVec3, Vec3A};
use serde::{Deserialize, Serialize};

use crate::SimError;

/// Global wind: a force on every free mass along `direction`, modulated by a travelling gust
/// `force_n · (1 + gust_amplitude · sin(2π (gust_frequency_hz · t − (d̂·x_rest) / gust_wavelength_m)))`.
/// The phase uses the mass's rest position, so wind adds no stiffness.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WindForce {
    /// Direction (normalised internally; zero disables the wind). Default +X.
    pub direction: [f32; 3],
    /// Mean force on each free mass, newtons. Default 1e-4.
    pub force_n: f32,
    /// Relative gust amplitude, 0 = steady. Default 0.5.
    pub gust_amplitude: f32,
    /// Gust frequency, hertz. Default 1.
    pub gust_frequency_hz: f32,
    /// Gust wavelength along the wind, metres (> 0). Default 1.
    pub gust_wavelength_m: f32,
}

impl Default for WindForce {
    fn default() -> Self {
        WindForce {
            direction: [1.0, 0.0, 0.0],
            force_n: 1e-4,
            gust_amplitude: 0.5,
            gust_frequency_hz: 1.0,
            gust_wavelength_m: 1.0,
        }
    }
}

/// A local interaction force: pushes free masses within `radius_m` of `point_m` away from it with
/// magnitude `strength_n · (1 − d/radius)²`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalForce {
    /// Centre, metres (mesh frame).
    pub point_m: [f32; 3],
    /// Radius of influence, metres (> 0).
    pub radius_m: f32,
    /// Force at the centre, newtons (negative pulls).
    pub strength_n: f32,
}

/// Motion of the mesh frame (all zero: the object is at rest).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrameMotion {
    /// Linear acceleration of the frame origin, m/s².
    pub linear_accel_m_per_s2: [f32; 3],
    /// Angular velocity of the frame, rad/s.
    pub angular_velocity_rad_per_s: [f32; 3],
    /// Angular acceleration of the frame, rad/s².
    pub angular_accel_rad_per_s2: [f32; 3],
}

/// Every external force acting on the free masses.
#[derive(Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ForceSet {
    /// Gravity, m/s² (mesh frame). Default (0, −9.81, 0).
    pub gravity_m_per_s2: [f32; 3],
    /// Weight `w` of the restoring force of eq. 3.37 on each tip mass, newtons. Default 0.01.
    pub restoring_weight_n: f32,
    /// Global wind (none by default).
    pub wind: Option<WindForce>,
    /// Object motion turned into inertial forces (at rest by default).
    pub motion: FrameMotion,
    /// Local interaction forces (none by default).
    pub local: Vec<LocalForce>,
}

impl Default for ForceSet {
    fn default() -> Self {
        ForceSet {
            gravity_m_per_s2: [0.0, -9.81, 0.0],
            restoring_weight_n: 0.01,
            wind: None,
            motion: FrameMotion::default(),
            local: Vec::new(),
        }
    }
}

impl Clone for ForceSet {
    fn clone(&self) -> Self {
        ForceSet {
            gravity_m_per_s2: self.gravity_m_per_s2,
            restoring_weight_n: self.restoring_weight_n,
            wind: self.wind.clone(),
            motion: self.motion.clone(),
            local: self.local.clone(),
        }
    }

    /// Copies `source` keeping this set's list of local forces (no allocation once it is as long
    /// as `source`'s): what a host that rewrites its forces every step wants.
    fn clone_from(&mut self, source: &Self) {
        self.gravity_m_per_s2 = source.gravity_m_per_s2;
        self.restoring_weight_n = source.restoring_weight_n;
        self.wind.clone_from(&source.wind);
        self.motion.clone_from(&source.motion);
        self.local.clone_from(&source.local);
    }
}

impl ForceSet {
    /// No external force at all (the restoring force stays: it is part of the fur model).
    pub fn none() -> Self {
        ForceSet { gravity_m_per_s2: [0.0; 3], ..ForceSet::default() }
    }

    /// Fails unless every value is finite and in range.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |name: &'static str, what: &str| Err(SimError::Parameter { name, what: what.to_owned() });
        let finite3 = |v: &[f32; 3]| v.iter().all(|c| c.is_finite());
        if !finite3(&self.gravity_m_per_s2) {
            return bad("gravity_m_per_s2", "not finite");
        }
        if !self.restoring_weight_n.is_finite() || self.restoring_weight_n < 0.0 {
            return bad("restoring_weight_n", "must be finite and ≥ 0");
        }
        if let Some(w) = &self.wind {
            if !finite3(&w.direction)
                || ![w.force_n, w.gust_amplitude, w.gust_frequency_hz].iter().all(|v| v.is_finite())
            {
                return bad("wind", "not finite");
            }
            if !(w.gust_wavelength_m.is_finite() && w.gust_wavelength_m > 0.0) {
                return bad("wind.gust_wavelength_m", "must be positive");
            }
        }
        let m = &self.motion;
        if !finite3(&m.linear_accel_m_per_s2)
            || !finite3(&m.angular_velocity_rad_per_s)
            || !finite3(&m.angular_accel_rad_per_s2)
        {
            return bad("motion", "not finite");
        }
        for l in &self.local {
            if !(finite3(&l.point_m) && l.strength_n.is_finite() && l.radius_m.is_finite() && l.radius_m > 0.0) {
                return bad("local", "point and strength must be finite, radius positive");
            }
        }
        Ok(())
    }
}

/// The force set prepared for one evaluation time: vectors converted, flags for the costly terms.
#[derive(Clone, Debug)]
pub(crate) struct ForceEval<'a> {
    /// Mass-proportional acceleration: gravity − frame linear acceleration.
    pub accel: Vec3A,
    pub rotating: bool,
    pub omega: Vec3A,
    pub alpha: Vec3A,
    pub wind: Option<(Vec3A, f32, f32, f32, f32)>,
    /// The local forces, read where evaluated (no copy per evaluation time).
    pub local: &'a [LocalForce],
    pub restoring_w: f32,
    time_s: f32,
    /// The evaluation time in f64 (the reference solver's forces).
    time_s64: f64,
}

impl ForceEval<'_> {
    pub fn new(f: &ForceSet, time_s: f64) -> ForceEval<'_> {
        let omega = Vec3A::from(f.motion.angular_velocity_rad_per_s);
        let alpha = Vec3A::from(f.motion.angular_accel_rad_per_s2);
        ForceEval {
            accel: Vec3A::from(f.gravity_m_per_s2) - Vec3A::from(f.motion.linear_accel_m_per_s2),
            rotating: omega != Vec3A::ZERO || alpha != Vec3A::ZERO,
            omega,
            alpha,
            wind: f.wind.as_ref().and_then(|w| {
                let d = Vec3A::from(w.direction).try_normalize()?;
                Some((d, w.force_n, w.gust_amplitude, w.gust_frequency_hz, 1.0 / w.gust_wavelength_m))
            }),
            local: &f.local,
            restoring_w: f.restoring_weight_n,
            time_s: time_s as f32,
            time_s64: time_s,
        }
    }

    /// True when only the mass-proportional term is active (the fast path of the kernels).
    #[inline]
    pub fn uniform_only(&self) -> bool {
        !self.rotating && self.wind.is_none() && self.local.is_empty()
    }

    /// External force on a free mass of `mass` at `x` (rest position `rest`) moving at `v`.
    #[inline]
    pub fn external(&self, mass: f32, x: Vec3A, v: Vec3A, rest: Vec3A) -> Vec3A {
        let mut f = self.accel * mass;
        if self.rotating {
            let inertial = self.alpha.cross(x) + self.omega.cross(self.omega.cross(x)) + 2.0 * self.omega.cross(v);
            f -= inertial * mass;
        }
        if let Some((d, force, amp, freq, inv_wl)) = self.wind {
            let phase = std::f32::consts::TAU * (freq * self.time_s - d.dot(rest) * inv_wl);
            f += d * (force * (1.0 + amp * phase.sin()));
        }
        for l in self.local {
            let (p, r, s) = (Vec3A::from(l.point_m), l.radius_m, l.strength_n);
            let delta = x - p;
            let dist = delta.length();
            if dist < r && dist > 1e-12 {
                let fall = 1.0 - dist / r;
                f += delta * (s * fall * fall / dist);
            }
        }
        f
    }
}

impl ForceEval<'_> {
    /// [`ForceEval::external`] in f64 with its exact Jacobians `(F, ∂F/∂x, ∂F/∂v)` (the reference
    /// solver): the inertial forces of a rotating frame depend on position and velocity, a local
    /// force on position; gravity and the wind (phase from the rest position) on neither.
    pub fn external_f64(&self, mass: f64, x: DVec3, v: DVec3, rest: Vec3A) -> (DVec3, DMat3, DMat3) {
        let mut f = self.accel.as_dvec3() * mass;
        let (mut jx, mut jv) = (DMat3::ZERO, DMat3::ZERO);
        if self.rotating {
            let (w, a) = (self.omega.as_dvec3(), self.alpha.as_dvec3());
            f -= (a.cross(x) + w.cross(w.cross(x)) + 2.0 * w.cross(v)) * mass;
            let (cw, ca) = (cross_matrix(w), cross_matrix(a));
            jx -= (ca + cw * cw) * mass;
            jv -= cw * (2.0 * mass);
        }
        if let Some((d, force, amp, freq, inv_wl)) = self.wind {
            let phase = std::f64::consts::TAU * (freq as f64 * self.time_s64 - d.dot(rest) as f64 * inv_wl as f64);
            f += d.as_dvec3() * (force as f64 * (1.0 + amp as f64 * phase.sin()));
        }
        for l in self.local {
            let (p, r, s) = (Vec3A::from(l.point_m), l.radius_m, l.strength_n);
            let (r, s) = (r as f64, s as f64);
            let delta = x - p.as_dvec3();
            let dist = delta.length();
            if dist < r && dist > 1e-12 {
                // f = δ g(d), g = s (1 − d/r)² / d: ∂f/∂x = g I + g′(d) d δ̂ δ̂ᵀ.
                let fall = 1.0 - dist / r;
                let g = s * fall * fall / dist;
                let dg = s * (-2.0 * fall / (r * dist) - fall * fall / (dist * dist));
                f += delta * g;
                let u = delta / dist;
                jx += DMat3::from_diagonal(DVec3::splat(g)) + outer(u, u) * (dg * dist);
            }
        }
        (f, jx, jv)
    }
}

/// `a bᵀ`.
#[inline]
pub(crate) fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The matrix of `y ↦ w × y`.
fn cross_matrix(w: DVec3) -> DMat3 {
    DMat3::from_cols(DVec3::new(0.0, w.z, -w.y), DVec3::new(-w.z, 0.0, w.x), DVec3::new(w.y, -w.x, 0.0))
}

/// The symmetric positive semi-definite part of `−J` ([`restoring_force_f64`]) that the implicit
/// solver's conjugate gradient uses: `−J = (w/l) (c (I − s sᵀ) + n⊥ n⊥ᵀ − c s n⊥ᵀ)` with
/// `n⊥ = n − (n·s) s`; the last term (it moves the tip along its own link, and is third order in
/// the deflection, `c ≈ θ²/2`, `|n⊥| ≈ θ`) is left out. Zero when the tip sits on its root.
pub(crate) fn restoring_stiffness_spd(root: DVec3, tip: DVec3, n: DVec3, w: f64) -> DMat3 {
    let d = tip - root;
    let l = d.length();
    if l.is_nan() || l <= 0.0 {
        return DMat3::ZERO;
    }
    let s = d / l;
    let c = 1.0 - n.dot(s);
    let np = n - s * n.dot(s);
    ((DMat3::IDENTITY - outer(s, s)) * c + outer(np, np)) * (w / l)
}

/// Restoring force of eq. 3.37 in f64 with its exact Jacobian with respect to the tip, `J`
/// (the root's is `−J`; not symmetric): with `s = (tip − root)/l`, `c = 1 − n·s`,
/// `F = (n − s) c w` and `J = (w/l) (−c I − (n − s) nᵀ)(I − s sᵀ)`. Zero when the tip sits on its
/// root.
pub(crate) fn restoring_force_f64(root: DVec3, tip: DVec3, n: DVec3, w: f64) -> (DVec3, DMat3) {
    let d = tip - root;
    let l = d.length();
    if l.is_nan() || l <= 0.0 {
        return (DVec3::ZERO, DMat3::ZERO);
    }
    let s = d / l;
    let c = 1.0 - n.dot(s);
    let u = n - s;
    let j = (DMat3::from_diagonal(DVec3::splat(-c)) - outer(u, n)) * (DMat3::IDENTITY - outer(s, s)) * (w / l);
    (u * (c * w), j)
}

/// Restoring force of eq. 3.37 on a tip at `tip` whose root is at `root`, rest direction `n`
/// (unit): `(n − s)(1 − n·s)·w` with `s` the unit scale vector (eq. 3.35). Zero when the tip sits
/// on its root (s undefined).
#[inline]
pub fn restoring_force(root: Vec3A, tip: Vec3A, n: Vec3A, w: f32) -> Vec3A {
    match (tip - root).try_normalize() {
        Some(s) => (n - s) * ((1.0 - n.dot(s)) * w),
        None => Vec3A::ZERO,
    }
}
