//! The skin moves: posing a simulated topology on an animated skin — the fur thesis's future work
//! (§3.4.1: the motion of the furry object is propagated into the mass points on its surface, so
//! the fur responds to any motion without modelled forces; `docs/design.md`, "Animated skins").
//!
//! Every mass hangs from one shell vertex: an anchored mass from the shell vertex whose root it
//! is, a free mass from the shell vertex of its hair's root (following its parent links down to
//! the skin). A pose gives each shell vertex a [`SkinTransform`] — the blended skinning matrix of
//! linear blend skinning and the morph offset of its vertex — and `BindPose::pose` moves the
//! model with it:
//! - anchored masses jump to their posed position, with the velocity of that jump over the step,
//!   so the skin drags the fur through its springs and their damping;
//! - the rest positions and rest directions of free masses (the restoring force of eq. 3.37, the
//!   wrong-side guard of §3.4.3, the scale vectors' fallback) follow the posed skin;
//! - a link between two hairs (a prism edge from one hair's tip to its neighbour's) keeps its
//!   bind strain: its rest length is scaled by how much the posed skin stretched the distance
//!   between its ends' rest positions. A link's rest length is the hairs' spacing on the skin,
//!   not a property of the hair; with bind lengths a bending knee or a stretching flank strained
//!   those links by 15 % (130 % at worst) on the walking Fox and laid its fur over (the guard
//!   froze a tenth of its hairs every step; `docs/performance.md`, "Animated characters").
//!   Links within one hair keep their length: the skin does not stretch the hair;
//! - a skin that moves faster than the caller's cut speed (a cut in the animation, a root that
//!   jumps metres in one frame) carries its fur along instead: each free mass moves with its own
//!   rest position and the anchors take no velocity, as a teleport does.
//!
//! Masses that hang from no shell vertex (a free mass with no path to an anchored root, an anchor
//! no shell vertex names) keep their bind pose.

use glam::{Mat3, Mat4, Vec3, Vec3A};
use rayon::prelude::*;

use crate::model::SimModel;
use crate::sentinel::NONE;

/// How one shell vertex moves from its bind pose to the pose of now: a position `p` of the bind
/// pose goes to `matrix · (p + morph_offset_m)` (glTF morph targets, then linear blend skinning
/// with the blended matrix `Σ wᵢ Mᵢ`), a direction `n` to `normalize(normal_matrix · n)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkinTransform {
    /// The blended skinning matrix (affine: the last row is `[0, 0, 0, 1]` up to rounding).
    pub matrix: Mat4,
    /// The matrix for directions: the cofactor of `matrix`'s upper 3×3 times the sign of its
    /// determinant (the inverse transpose up to a positive factor, defined even when singular).
    pub normal_matrix: Mat3,
    /// The morph targets' displacement of the vertex, bind frame, metres.
    pub morph_offset_m: Vec3,
}

impl SkinTransform {
    /// No motion.
    pub const IDENTITY: SkinTransform =
        SkinTransform { matrix: Mat4::IDENTITY, normal_matrix: Mat3::IDENTITY, morph_offset_m: Vec3::ZERO };

    /// The transform of a blended skinning matrix and a morph offset, with its normal matrix.
    pub fn new(matrix: Mat4, morph_offset_m: Vec3) -> SkinTransform {
        SkinTransform { matrix, normal_matrix: normal_matrix(&matrix), morph_offset_m }
    }

    fn is_finite(&self) -> bool {
        self.matrix.is_finite() && self.normal_matrix.is_finite() && self.morph_offset_m.is_finite()
    }
}

/// The cofactor matrix of `m`'s upper 3×3 times the sign of its determinant: it maps normals as
/// the inverse transpose does, up to a positive factor, and stays defined when `m` is singular
/// (a joint scaled to zero); a mirrored matrix (negative determinant) keeps normals outward.
pub fn normal_matrix(m: &Mat4) -> Mat3 {
    let m3 = Mat3::from_mat4(*m);
    let (c0, c1, c2) = (m3.x_axis, m3.y_axis, m3.z_axis);
    let det = m3.determinant();
    let sign = if det < 0.0 { -1.0 } else { 1.0 };
    Mat3::from_cols(c1.cross(c2), c2.cross(c0), c0.cross(c1)) * sign
}

/// What one [`crate::Simulator::pose_skin`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SkinMove {
    /// The fastest anchored mass's speed over the step, m/s (before any cut).
    pub max_anchor_speed_m_per_s: f32,
    /// True when that speed exceeded the cut speed, so the fur was carried along.
    pub cut: bool,
}

/// The bind pose of a model and which shell vertex every mass hangs from; built on the first
/// pose, so topologies that never move pay nothing.
#[derive(Debug)]
pub(crate) struct BindPose {
    /// Per internal mass: the shell vertex it hangs from, or NONE.
    attach: Vec<u32>,
    /// Per internal mass: rest position in the bind pose.
    rest: Vec<Vec3A>,
    /// Per free mass: rest direction of its restoring link in the bind pose.
    rest_n: Vec<Vec3A>,
    /// Per tip: rest direction in the bind pose.
    tip_n: Vec<Vec3A>,
    /// Per internal mass: its posed rest position (scratch reused every pose).
    posed: Vec<Vec3A>,
    /// The links between masses that hang from different shell vertices (prism edges between
    /// hairs): their rest lengths follow the skin's stretch between their ends.
    between: Vec<BetweenLink>,
}

/// A link between two hairs: its ends, its bind rest length, the bind distance of its ends' rest
/// positions, and where its rest length is kept — the adjacency entries of its free ends (as
/// `(free mass, entry)`) and its energy spring (NONE where absent).
#[derive(Clone, Copy, Debug)]
struct BetweenLink {
    ends: [u32; 2],
    rest: f32,
    bind_distance: f32,
    adj: [(u32, u32); 2],
    spring: u32,
}

/// Masses per parallel task when posing.
const POSE_CHUNK: usize = 4096;

impl BindPose {
    pub fn new(model: &SimModel) -> BindPose {
        let (n, nf) = (model.n, model.n_free);
        let mut attach = vec![NONE; n];
        // Anchors: the root of the first shell vertex that names them.
        for (s, &slot) in model.shell_tip.iter().enumerate() {
            if slot != NONE {
                let root = model.tips[slot as usize].root as usize;
                if root >= nf && attach[root] == NONE {
                    attach[root] = s as u32;
                }
            }
        }
        // Tips whose root is free (chains hang through free masses): their shell vertex too, so
        // a chain whose middle has no path down still follows its vertex.
        for (s, &slot) in model.shell_tip.iter().enumerate() {
            if slot != NONE {
                let tip = model.tips[slot as usize].tip as usize;
                if attach[tip] == NONE {
                    attach[tip] = s as u32;
                }
            }
        }
        // Free masses by increasing depth: the parent of the restoring link is nearer the skin,
        // so it is attached first (free masses are ordered by depth).
        for k in 0..nf {
            let p = model.rest_parent[k];
            if p != NONE && attach[p as usize] != NONE {
                attach[k] = attach[p as usize];
            }
        }
        let hangs_apart = |a: usize, b: usize| attach[a] != NONE && attach[b] != NONE && attach[a] != attach[b];
        let entry = |k: usize, other: usize| -> (u32, u32) {
            if k >= nf {
                return (NONE, NONE);
            }
            let start = model.adj_start[k] as usize;
            match model.adj_of(k).iter().position(|l| l.other as usize == other) {
                Some(i) => (k as u32, (start + i) as u32),
                None => (NONE, NONE),
            }
        };
        // One entry per spring (every force link between two hairs is a spring; sticks join a
        // hair's own masses).
        let between: Vec<BetweenLink> = model
            .springs
            .iter()
            .enumerate()
            .filter(|(_, ([a, b], _, _))| hangs_apart(*a as usize, *b as usize))
            .map(|(s, &([a, b], rest, _))| {
                let (a, b) = (a as usize, b as usize);
                BetweenLink {
                    ends: [a as u32, b as u32],
                    rest,
                    bind_distance: model.rest[a].distance(model.rest[b]),
                    adj: [entry(a, b), entry(b, a)],
                    spring: s as u32,
                }
            })
            .collect();
        BindPose {
            between,
            attach,
            rest: model.rest.clone(),
            rest_n: model.rest_n.clone(),
            tip_n: model.tips.iter().map(|t| t.n).collect(),
            posed: model.rest.clone(),
        }
    }

    /// The bind pose as a compute solver reads it (`compute.rs`).
    pub fn compute_form(&self, model: &SimModel) -> crate::ComputePose {
        let v3 = |v: &Vec3A| v.to_array();
        crate::ComputePose {
            attach: self.attach.clone(),
            bind_rest: self.rest.iter().map(v3).collect(),
            bind_restoring_n: self.rest_n[..model.n_free].iter().map(v3).collect(),
            bind_tip_n: self.tip_n.iter().map(v3).collect(),
            between: self
                .between
                .iter()
                .map(|b| crate::ComputeBetween {
                    ends: b.ends,
                    rest: b.rest,
                    bind_distance: b.bind_distance,
                    entries: b.adj.map(|(_, e)| e),
                })
                .collect(),
        }
    }

    /// Checks `transforms` (one per shell vertex, finite).
    pub fn check(model: &SimModel, transforms: &[SkinTransform]) -> Result<(), String> {
        if transforms.len() != model.shell_tip.len() {
            return Err(format!("{} transforms for {} shell vertices", transforms.len(), model.shell_tip.len()));
        }
        match transforms.iter().position(|t| !t.is_finite()) {
            Some(s) => Err(format!("the transform of shell vertex {s} is not finite")),
            None => Ok(()),
        }
    }

    /// Moves `model`, positions `x`/`x_next` and velocities `v`/`v_next` (internal order) to the
    /// pose `transforms` at the end of a step of `dt_s` seconds; see the module documentation.
    #[allow(clippy::too_many_arguments)]
    pub fn pose(
        &mut self,
        model: &mut SimModel,
        transforms: &[SkinTransform],
        dt_s: f64,
        cut_speed_m_per_s: f32,
        x: &mut [Vec3A],
        x_next: &mut [Vec3A],
        v: &mut [Vec3A],
        v_next: &mut [Vec3A],
    ) -> SkinMove {
        let nf = model.n_free;
        let posed_of = |s: u32, p: Vec3A| {
            if s == NONE {
                return p;
            }
            let t = &transforms[s as usize];
            Vec3A::from(t.matrix.transform_point3(Vec3::from(p) + t.morph_offset_m))
        };
        self.posed
            .par_chunks_mut(POSE_CHUNK)
            .zip(self.attach.par_chunks(POSE_CHUNK).zip(self.rest.par_chunks(POSE_CHUNK)))
            .for_each(|(out, (att, rest))| {
                for ((o, &s), &p) in out.iter_mut().zip(att).zip(rest) {
                    *o = posed_of(s, p);
                }
            });
        let inv_dt = (1.0 / dt_s) as f32;
        let max_speed =
            self.posed[nf..].iter().zip(&x[nf..]).map(|(p, q)| p.distance(*q)).fold(0.0f32, f32::max) * inv_dt;
        // A non-finite speed (a huge jump) is a cut too.
        let cut = max_speed.is_nan() || max_speed > cut_speed_m_per_s;
        for ((xk, rest), &posed) in x[..nf].iter_mut().zip(&mut model.rest[..nf]).zip(&self.posed[..nf]) {
            if cut {
                *xk += posed - *rest;
            }
            *rest = posed;
        }
        for k in nf..model.n {
            let p = self.posed[k];
            let vel = if cut { Vec3A::ZERO } else { (p - x[k]) * inv_dt };
            (x[k], x_next[k], v[k], v_next[k]) = (p, p, vel, vel);
            model.rest[k] = p;
        }
        // Links between hairs keep their bind strain: the skin's stretch between their ends
        // stretches their rest length alike, so a bending joint does not pull the tips sideways.
        if !self.between.is_empty() {
            for b in &self.between {
                let [i, j] = b.ends.map(|e| e as usize);
                let rest = if b.bind_distance > 0.0 {
                    b.rest * (self.posed[i].distance(self.posed[j]) / b.bind_distance)
                } else {
                    b.rest
                };
                for (k, e) in b.adj {
                    if k != NONE {
                        model.set_adj_rest(k as usize, e as usize, rest);
                    }
                }
                model.springs[b.spring as usize].1 = rest;
            }
            model.rest_version += 1;
        }
        // Directions: the restoring links of free masses and the tips.
        let dir = |s: u32, n: Vec3A| {
            if s == NONE {
                return n;
            }
            let m = transforms[s as usize].normal_matrix;
            Vec3A::from(m * Vec3::from(n)).try_normalize().unwrap_or(n)
        };
        let groups = &mut model.groups;
        for k in 0..nf {
            let n = dir(self.attach[k], self.rest_n[k]);
            model.rest_n[k] = n;
            for a in 0..3 {
                groups.rest_n[a][k] = n[a];
            }
        }
        for (t, &n0) in model.tips.iter_mut().zip(&self.tip_n) {
            t.n = dir(self.attach[t.tip as usize], n0);
            for a in 0..3 {
                groups.tip_n[a][t.tip as usize] = t.n[a];
            }
        }
        SkinMove { max_anchor_speed_m_per_s: max_speed, cut }
    }
}
