//! Frame conversion: scene quantities (world metres, seconds) brought into one pack's mesh frame,
//! where its fur simulation and its grass force field work. [`crate::World`] steps; this module
//! only converts.
//!
//! The fur simulation runs in each pack's mesh frame, in the mesh's own units (the topology was
//! baked in them). With the pack's model matrix at the current time (rotation `R`, uniform scale
//! `s`): points go through the inverse model matrix, directions are rotated by `R⁻¹`, lengths,
//! accelerations and forces are divided by `s` (`F = m·a` with lengths in mesh units). Object
//! motion is the motion path differentiated over one time step `h` (fur thesis §3.4, inertial
//! forces): linear acceleration `(p(t+h) − 2p(t) + p(t−h))/h²`, angular velocity from
//! `q(t+h)·q(t−h)⁻¹` over `2h` and angular acceleration from the angular velocities at `t ± h` —
//! a key's velocity change arrives as one step of acceleration, as it would from a game's
//! transform updates. Teleports are not part of the path, so a jump adds no inertial force.
//!
//! The grass force field is computed over the blade field's grid in the mesh frame: wind sources,
//! colliders and windless areas are moved into that frame (positions by the inverse model matrix,
//! radii by `1/s`, a source's power by `s^−σ` so grass thesis eq. 4.1 gives the same force at the
//! same world distance), the global wind is rotated. Forces stay horizontal `(x, z)`; rotations
//! about axes other than +y are not meaningful for grass and windless boxes are bounded
//! conservatively.

use furbake_grass::ForceScene;
use furbake_sim::{ForceSet, FrameMotion, LocalForce, WindForce};
use glam::{Mat4, Quat, Vec2, Vec3};

use crate::scene::{Collider, Effect, Effects, Interaction, WindSource};

/// Mean wind force on one free fur mass per m/s of wind speed, newtons (world units). With the
/// default hair (1e-4 kg per hair) a 2 m/s breeze pushes a tip with 1e-4 N, furbake-sim's default
/// wind. Point wind sources count their eq. 4.1 strength as m/s of wind speed.
pub const FUR_WIND_N_PER_M_PER_S: f32 = 5e-5;
/// Wavelength of the fur wind's travelling gust along the wind, world metres.
pub const FUR_GUST_WAVELENGTH_M: f32 = 4.0;
/// Grass force units per m/s of global wind (the keyframe tables are indexed by force magnitude).
pub const GRASS_FORCE_PER_M_PER_S: f32 = 1.0;
/// Push of a collider on grass at and inside its surface, force units.
pub const GRASS_COLLIDER_STRENGTH: f32 = 2.0;
/// Distance beyond a collider's surface over which its push fades out, as a fraction of its
/// (smallest) radius.
pub const GRASS_COLLIDER_FALLOFF: f32 = 0.5;
/// Lower clamp of a point source's distance, metres (as furbake-grass's default).
const POINT_SOURCE_MIN_DISTANCE_M: f32 = 0.05;

/// A pack's mesh frame at one time: rotation, uniform scale and the inverse model matrix.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MeshFrame {
    pub(crate) rotation: Quat,
    pub(crate) scale: f32,
    inverse: Mat4,
}

impl MeshFrame {
    /// The frame of `model` (rotation, translation, positive uniform scale — what scenes and
    /// teleports produce, so the matrix is invertible).
    pub(crate) fn of(model: Mat4) -> MeshFrame {
        let (scale, rotation, _) = model.to_scale_rotation_translation();
        MeshFrame { rotation, scale: scale.x, inverse: model.inverse() }
    }

    /// A world point in mesh coordinates.
    pub(crate) fn point(&self, p: Vec3) -> Vec3 {
        self.inverse.transform_point3(p)
    }

    /// A world acceleration (or force per unit mass, or offset) in mesh units.
    pub(crate) fn vector(&self, v: Vec3) -> Vec3 {
        self.rotation.inverse() * v / self.scale
    }
}

/// Linear velocity, angular velocity and their accelerations of a motion path at `t`, world
/// frame, by central differences over `h` (see the module doc). `path(t)` gives the model matrix;
/// times before 0 are clamped to 0.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PathMotion {
    pub(crate) velocity: Vec3,
    pub(crate) acceleration: Vec3,
    pub(crate) angular_velocity: Vec3,
    pub(crate) angular_acceleration: Vec3,
}

pub(crate) fn path_motion(path: impl Fn(f64) -> Mat4, t: f64, h: f64) -> PathMotion {
    let place = |t: f64| {
        let (_, r, p) = path(t.max(0.0)).to_scale_rotation_translation();
        (p, r)
    };
    let (p0, q0) = place(t - h);
    let (p1, q1) = place(t);
    let (p2, q2) = place(t + h);
    let hf = h as f32;
    let omega = |a: Quat, b: Quat, span: f32| {
        let d = (b * a.inverse()).normalize();
        // The shortest rotation (q and −q are the same rotation).
        let d = if d.w < 0.0 { -d } else { d };
        let (axis, angle) = d.to_axis_angle();
        if angle.is_finite() { axis * (angle / span) } else { Vec3::ZERO }
    };
    let w_back = omega(q0, q1, hf);
    let w_fwd = omega(q1, q2, hf);
    PathMotion {
        velocity: (p2 - p0) / (2.0 * hf),
        acceleration: (p2 - 2.0 * p1 + p0) / (hf * hf),
        angular_velocity: omega(q0, q2, 2.0 * hf),
        angular_acceleration: (w_fwd - w_back) / hf,
    }
}

/// The weight of the restoring force (fur thesis eq. 3.37; the scene's
/// `wrong_side_guard.restoring_weight_n`, or furbake-sim's default without a guard), a force in
/// newtons, in the mesh's units: divided by the scale like every force, so fur in a centimetre
/// mesh placed at scale 0.01 stands up as the same fur in metres does.
pub(crate) fn restoring_weight(effects: &Effects, frame: &MeshFrame) -> f32 {
    let newtons = effects.wrong_side_guard.map_or(ForceSet::default().restoring_weight_n, |g| g.restoring_weight_n);
    newtons / frame.scale
}

/// The inertial frame motion of furbake-sim (mesh frame at `frame`), scaled by `inertia_scale`.
pub(crate) fn frame_motion(motion: &PathMotion, frame: &MeshFrame, inertia_scale: f32) -> FrameMotion {
    let to_mesh = frame.rotation.inverse();
    FrameMotion {
        linear_accel_m_per_s2: (frame.vector(motion.acceleration) * inertia_scale).to_array(),
        angular_velocity_rad_per_s: (to_mesh * motion.angular_velocity * inertia_scale).to_array(),
        angular_accel_rad_per_s2: (to_mesh * motion.angular_acceleration * inertia_scale).to_array(),
    }
}

/// Wind of a point source at `p` (grass thesis eq. 4.1 with the full 3D direction):
/// `normalize(p − W) · ω / max(|p − W|, 5 cm)^σ`, in m/s of wind speed.
pub(crate) fn point_source_wind(s: &WindSource, p: Vec3) -> Vec3 {
    let wp = p - Vec3::from(s.position);
    let d = wp.length();
    if d == 0.0 {
        return Vec3::ZERO;
    }
    wp / d * (s.power / d.max(POINT_SOURCE_MIN_DISTANCE_M).powf(s.falloff_exponent))
}

/// Which force effects are on this step (events switch them; see `crate::scene::Event`): one
/// flag per entry of [`Effect::FORCES`], in that order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ForcesOn([bool; Effect::FORCES.len()]);

impl ForcesOn {
    pub(crate) const ALL: ForcesOn = ForcesOn([true; Effect::FORCES.len()]);

    /// True when force `effect` is switched on (false for effects that are not forces).
    pub(crate) fn has(self, effect: Effect) -> bool {
        Effect::FORCES.iter().position(|&f| f == effect).is_some_and(|i| self.0[i])
    }

    /// Switches `effects` (every force when empty) on or off.
    pub(crate) fn set(&mut self, effects: &[Effect], value: bool) {
        for (flag, force) in self.0.iter_mut().zip(Effect::FORCES) {
            if effects.is_empty() || effects.contains(&force) {
                *flag = value;
            }
        }
    }
}

/// Fur wind in the mesh frame: the global wind plus every point source evaluated at the pack's
/// `origin` (eq. 4.1 in 3D: furbake-sim has one wind per simulation, so sources act on fur
/// uniformly), as furbake-sim's travelling-gust wind.
pub(crate) fn fur_wind(effects: &Effects, on: ForcesOn, origin: Vec3, frame: &MeshFrame) -> WindForce {
    let mut v = Vec3::ZERO;
    if on.has(Effect::Wind) {
        v += effects.wind.map_or(Vec3::ZERO, |w| Vec3::from(w.velocity_m_per_s));
    }
    if on.has(Effect::WindSources) {
        for s in &effects.wind_sources {
            v += point_source_wind(s, origin);
        }
    }
    let (amp, hz) = effects.wind.map_or((0.0, 0.0), |w| (w.gust_amplitude, w.gust_frequency_hz));
    WindForce {
        direction: (frame.rotation.inverse() * v).normalize_or_zero().to_array(),
        force_n: FUR_WIND_N_PER_M_PER_S * v.length() / frame.scale,
        gust_amplitude: amp,
        gust_frequency_hz: hz,
        gust_wavelength_m: FUR_GUST_WAVELENGTH_M / frame.scale,
    }
}

/// The interaction brush at `point` (world metres) as a local force in the mesh frame.
pub(crate) fn interaction_force(it: &Interaction, point: Vec3, frame: &MeshFrame) -> LocalForce {
    LocalForce {
        point_m: frame.point(point).to_array(),
        radius_m: it.radius_m / frame.scale,
        strength_n: it.strength_n / frame.scale,
    }
}

/// Writes the grass force scene of `effects` at time `t` in the mesh frame into `out` (cleared
/// first; its vectors keep their capacity, so a per-step call does not allocate once warm).
pub(crate) fn grass_force_scene(effects: &Effects, on: ForcesOn, t: f64, frame: &MeshFrame, out: &mut ForceScene) {
    out.global_wind = Vec2::ZERO;
    out.sources.clear();
    out.colliders.clear();
    out.blockers.clear();
    if let (Some(w), true) = (effects.wind, on.has(Effect::Wind)) {
        let gust = 1.0 + w.gust_amplitude * (std::f64::consts::TAU * w.gust_frequency_hz as f64 * t).sin() as f32;
        let v = frame.rotation.inverse() * Vec3::from(w.velocity_m_per_s);
        out.global_wind = Vec2::new(v.x, v.z) * (GRASS_FORCE_PER_M_PER_S * gust);
    }
    if on.has(Effect::WindSources) {
        for s in &effects.wind_sources {
            out.sources.push(furbake_grass::BladeWindSource {
                position_m: frame.point(Vec3::from(s.position)),
                power: s.power * frame.scale.powf(-s.falloff_exponent),
                falloff_exponent: s.falloff_exponent,
                delayed: s.delayed_attenuation,
            });
        }
    }
    if on.has(Effect::Collisions) {
        for c in &effects.collisions {
            out.colliders.push(match *c {
                Collider::Sphere { center, radius_m } => furbake_grass::BladeCollider::Sphere {
                    center_m: frame.point(Vec3::from(center)),
                    radius_m: radius_m / frame.scale,
                    strength: GRASS_COLLIDER_STRENGTH,
                    falloff_m: GRASS_COLLIDER_FALLOFF * radius_m / frame.scale,
                },
                Collider::Ellipsoid { center, radii_m } => {
                    let r = Vec3::from(radii_m) / frame.scale;
                    furbake_grass::BladeCollider::Ellipsoid {
                        center_m: frame.point(Vec3::from(center)),
                        radii_m: r,
                        strength: GRASS_COLLIDER_STRENGTH,
                        falloff_m: GRASS_COLLIDER_FALLOFF * r.min_element(),
                    }
                }
            });
        }
    }
    for a in &effects.windless_areas {
        // The box's eight corners in the mesh frame, bounded in xz.
        let (lo, hi) = (Vec3::from(a.min), Vec3::from(a.max));
        let (mut min, mut max) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let m = frame.point(c);
            min = min.min(Vec2::new(m.x, m.z));
            max = max.max(Vec2::new(m.x, m.z));
        }
        out.blockers.push(furbake_grass::WindBlocker { min_m: min, max_m: max });
    }
}
