//! Shell shearing on the CPU (fur thesis §3.4.2, eq. 3.35–3.36) — the reference the vertex shaders
//! must match — and the wrong-side-scale guard (§3.4.3): the `n·s < cos α` test, an impulse along
//! the normal, and a scale vector frozen at its last good value until the tip is back.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::model::SimModel;

/// Scale vector of eq. 3.35: `s = (p_tip − p_root)/|p_tip − p_root|`, or `None` when the tip sits
/// on its root.
pub fn scale_vector(root: Vec3, tip: Vec3) -> Option<Vec3> {
    (tip - root).try_normalize()
}

/// Horizontal shell offset of eq. 3.36 for layer `layer` of `layers` (0 = skin):
/// `h = (layer/layers)^k (s − n)`, unitless (multiply by the fur length for metres).
pub fn shell_offset(layer: u32, layers: u32, exponent_k: f32, s: Vec3, n: Vec3) -> Vec3 {
    if layers == 0 {
        return Vec3::ZERO;
    }
    (layer as f32 / layers as f32).powf(exponent_k) * (s - n)
}

/// Position of a shell vertex: the skin vertex moved `fur_length · layer/layers` along the normal
/// (the fixed inter-shell distance) plus the horizontal offset of eq. 3.36 scaled by the fur
/// length, so the outermost layer ends at `skin + s · fur_length`.
pub fn shell_vertex_position(
    skin: Vec3,
    n: Vec3,
    s: Vec3,
    layer: u32,
    layers: u32,
    fur_length_m: f32,
    exponent_k: f32,
) -> Vec3 {
    let t = if layers == 0 { 0.0 } else { layer as f32 / layers as f32 };
    let offset = n * t + shell_offset(layer, layers, exponent_k, s, n);
    // A scale vector pointing into the surface (§3.4.3) would put outer layers below the skin:
    // the inward component is dropped so fur lies flat instead (the shader does the same).
    let offset = offset - offset.dot(n).min(0.0) * n;
    skin + offset * fur_length_m
}

/// Parameters of the wrong-side-scale guard (§3.4.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GuardSettings {
    /// Run the guard (default true). Off, scale vectors follow the masses wherever they go.
    pub enabled: bool,
    /// Threshold angle α between the vertex normal and the scale vector, degrees (0 < α < 90).
    /// Default 80.
    pub max_angle_deg: f32,
    /// Speed added along the normal to a tip when the test fires, m/s. Default 0.05.
    pub impulse_m_per_s: f32,
}

impl Default for GuardSettings {
    fn default() -> Self {
        GuardSettings { enabled: true, max_angle_deg: 80.0, impulse_m_per_s: 0.05 }
    }
}

/// What one guard pass did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct GuardOutcome {
    pub triggers: u32,
    pub frozen: u32,
    pub kinetic_added_j: f64,
}

/// Per tip: the scale vector handed to rendering and whether it is frozen.
#[derive(Clone, Debug)]
pub(crate) struct GuardState {
    pub scale: Vec<Vec3A>,
    pub frozen: Vec<bool>,
    /// The next state, written by a solver pass that runs the guard itself and made current by
    /// [`GuardState::commit`] once the step is accepted (a rejected step leaves the guard as it was).
    pub scale_next: Vec<Vec3A>,
    pub frozen_next: Vec<bool>,
    kick: Vec<bool>,
}

impl GuardState {
    pub fn new(model: &SimModel) -> GuardState {
        GuardState {
            scale: model.tips.iter().map(|t| t.n).collect(),
            frozen: vec![false; model.tips.len()],
            scale_next: model.tips.iter().map(|t| t.n).collect(),
            frozen_next: vec![false; model.tips.len()],
            kick: vec![false; model.tips.len()],
        }
    }

    /// After the skin moved (the tips' rest directions changed): a kept scale vector that now
    /// points past the guard's angle from its tip's direction is replaced by that direction, so
    /// a frozen vector never shows fur inside the posed surface.
    pub fn follow_rest_directions(&mut self, model: &SimModel, p: &GuardSettings) {
        let cos_a = if p.enabled { p.max_angle_deg.to_radians().cos() } else { -1.0 };
        for (s, t) in self.scale.iter_mut().zip(&model.tips) {
            if t.n.dot(*s) < cos_a {
                *s = t.n;
            }
        }
    }

    /// Makes the state a solver pass wrote into `scale_next`, `frozen_next` current.
    pub fn commit(&mut self) {
        std::mem::swap(&mut self.scale, &mut self.scale_next);
        std::mem::swap(&mut self.frozen, &mut self.frozen_next);
    }

    /// Tests every tip against `cos α`; updates scale vectors; applies impulses to `v`.
    /// Per-tip work runs in parallel; impulses are applied afterwards in tip order.
    pub fn apply(&mut self, model: &SimModel, p: &GuardSettings, x: &[Vec3A], v: &mut [Vec3A]) -> GuardOutcome {
        let cos_a = p.max_angle_deg.to_radians().cos();
        let enabled = p.enabled;
        self.kick.resize(model.tips.len(), false);
        let test = |(t, (scale, (frozen, kick))): (&crate::model::Tip, (&mut Vec3A, (&mut bool, &mut bool)))| {
            *kick = false;
            let s = (x[t.tip as usize] - x[t.root as usize]).try_normalize();
            if !enabled {
                *scale = s.unwrap_or(t.n);
                return;
            }
            match s.filter(|s| t.n.dot(*s) >= cos_a) {
                Some(s) => {
                    *scale = s;
                    *frozen = false;
                }
                // Frozen tips wait for the restoring force; a fresh failure freezes and kicks.
                None if !*frozen => {
                    *frozen = true;
                    *kick = true;
                }
                None => {}
            }
        };
        let items = model.tips.iter().zip(self.scale.iter_mut().zip(self.frozen.iter_mut().zip(self.kick.iter_mut())));
        if model.tips.len() < 4096 {
            items.for_each(test);
        } else {
            model
                .tips
                .par_iter()
                .zip(self.scale.par_iter_mut().zip(self.frozen.par_iter_mut().zip(self.kick.par_iter_mut())))
                .with_min_len(1024)
                .for_each(test);
        }
        let mut out = GuardOutcome::default();
        for (t, _) in model.tips.iter().zip(&self.kick).filter(|(_, k)| **k) {
            // Kick the tip out along the normal.
            out.triggers += 1;
            let vi = v[t.tip as usize];
            let nv = vi + p.impulse_m_per_s * t.n;
            let m = model.mass[t.tip as usize] as f64;
            out.kinetic_added_j += 0.5 * m * (nv.length_squared() as f64 - vi.length_squared() as f64);
            v[t.tip as usize] = nv;
        }
        out.frozen = self.frozen.iter().filter(|&&f| f).count() as u32;
        out
    }
}
