//! The solver-ready model as flat arrays, for solvers that run elsewhere (compute shaders): the
//! same free-mass ordering, per-mass link adjacency, restoring links (eq. 3.37), rigid parent
//! links, tips and guard (§3.4.3, eq. 3.35) the CPU kernels read (`model.rs`), and the simulator's
//! current state, so that a GPU solver can take over from the CPU at any step. Indices are
//! internal (free masses first); [`NO_LINK`] marks an absent link.
//!
//! What such a solver must reproduce per substep of length `h` (as `solvers/fused.rs`): for each
//! free mass `k`, the force `F = (F_ext + F_restoring) + Σ_links (d·k(1 − rest/|d|) + Δv·c)`
//! with the links summed in adjacency order; the explicit update `v' = v + F·(h/m)`,
//! `x' = x + h v'` (eq. 3.20–3.22) or the stick solver's `v' = (v + F h/m + v_p a)/(1 + a)`,
//! `a = h c_p/m` towards a rigid parent; then, when [`ComputeModel::project_sticks`], the mass put
//! back at its stick's length from its anchored parent with its velocity along the stick
//! removed. After the last substep, the guard on every tip (roots are anchored).
//!
//! XPBD (`solvers/xpbd.rs`) instead predicts `Δx = h (v + Δv)` with the external and restoring
//! forces (the restoring stiffness `2w/L` on the diagonal), projects
//! [`ComputeModel::xpbd`]'s links colour by colour (`iterations` symmetric sweeps: colours up,
//! then down; one colour's links share no free mass), and ends with `x' = x + Δx`, `v' = Δx/h` and
//! the same projection and guard; it never substeps.
//!
//! On an animated skin ([`Simulator::pose_skin`]) the model also carries its bind pose
//! ([`ComputePose`]): before a step, a compute solver poses it as `skin.rs` does — every mass's
//! rest position `T_s · (bind + morph)` through the transform of the shell vertex `s` it hangs
//! from, anchored masses moved there with the velocity of the jump over the step (or carried
//! along, with no velocity, when the fastest anchor beat the cut speed), free masses' and tips'
//! rest directions turned by the normal matrix, links between hairs keeping their bind strain,
//! anchored sticks re-projected and the guard's frozen scale vectors that now lie past its angle
//! reset to the rest direction.

use crate::sentinel::NONE;
use crate::shell::GuardSettings;
use crate::{SimError, Simulator, SolverKind};

/// An absent link in [`ComputeModel`] (no restoring link, no rigid parent, a bare shell vertex).
pub const NO_LINK: u32 = NONE;

/// The velocity update a compute solver applies (the lane-group kernels' modes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ComputeUpdate {
    /// Symplectic Euler (fur thesis eq. 3.20–3.25).
    Explicit,
    /// Explicit with implicit damping towards each rigid parent (§3.4.1, the stick solver).
    Stick,
    /// XPBD with this many symmetric Gauss–Seidel sweeps per step.
    Xpbd {
        /// Sweeps per step (`SolverSettings::xpbd_iterations`).
        iterations: u32,
    },
}

/// One XPBD link (`solvers/xpbd.rs`): `ends[0]` free, `ends[1]` free or anchored.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComputeXpbdLink {
    /// Its two masses, internal indices.
    pub ends: [u32; 2],
    /// Rest length, metres.
    pub rest: f32,
    /// Compliance `1/k` (0 for a stick, infinite for a link without stiffness).
    pub compliance: f32,
    /// Viscosity `c`, N·s/m (eq. 3.24).
    pub c: f32,
    /// The ends' inverse masses (0 for an anchored end).
    pub inv_mass: [f32; 2],
    /// The link entry (index into [`ComputeModel::link_other`]) whose rest length it shares.
    pub entry: u32,
}

/// A link between two hairs on a posed skin: its rest length follows the skin's stretch between
/// its ends, `rest · |posed(a) − posed(b)| / bind_distance` (`skin.rs`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComputeBetween {
    /// Its two masses, internal indices.
    pub ends: [u32; 2],
    /// Rest length in the bind pose, metres.
    pub rest: f32,
    /// Distance between the ends' bind rest positions, metres (0: the rest length stays).
    pub bind_distance: f32,
    /// The link entries (indices into [`ComputeModel::link_other`]) holding its rest length from
    /// either free end, or [`NO_LINK`].
    pub entries: [u32; 2],
}

/// The bind pose of a model on an animated skin ([`ComputeModel::pose`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ComputePose {
    /// Per mass: the shell vertex it hangs from, or [`NO_LINK`] (it keeps its bind pose).
    pub attach: Vec<u32>,
    /// Per mass: rest position in the bind pose, metres.
    pub bind_rest: Vec<[f32; 3]>,
    /// Per free mass: the restoring link's rest direction in the bind pose.
    pub bind_restoring_n: Vec<[f32; 3]>,
    /// Per tip: rest direction in the bind pose.
    pub bind_tip_n: Vec<[f32; 3]>,
    /// The links between hairs.
    pub between: Vec<ComputeBetween>,
}

/// XPBD's links, coloured: colour `i`'s links are `links[colour_start[i]..colour_start[i + 1]]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ComputeXpbd {
    /// The links, colour-major.
    pub links: Vec<ComputeXpbdLink>,
    /// Where each colour starts (`colours + 1` entries).
    pub colour_start: Vec<u32>,
}

/// One tip of the shell's scale vectors (eq. 3.35): its anchored root mass, its free tip mass and
/// the rest direction (the vertex normal, unit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComputeTip {
    /// Root mass (anchored), internal index.
    pub root: u32,
    /// Tip mass (free), internal index.
    pub tip: u32,
    /// Rest direction, unit.
    pub n: [f32; 3],
}

/// The model and state of a [`Simulator`] as a compute solver reads them
/// ([`Simulator::compute_model`]). Per-mass arrays have `masses` entries (free masses first),
/// per-free-mass arrays `free` entries.
#[derive(Clone, Debug)]
pub struct ComputeModel {
    /// The update rule.
    pub update: ComputeUpdate,
    /// Every mass.
    pub masses: u32,
    /// The free masses (internal indices `0..free`; the rest are anchored and never move).
    pub free: u32,
    /// Internal index → the topology's mass index.
    pub order: Vec<u32>,
    /// Rest position per mass, metres (mesh frame).
    pub rest: Vec<[f32; 3]>,
    /// Current position and velocity per mass.
    pub positions: Vec<[f32; 3]>,
    /// Current velocity per mass, m/s.
    pub velocities: Vec<[f32; 3]>,
    /// Mass per free mass, kg.
    pub mass: Vec<f32>,
    /// Links of free mass `k`: `links_start[k]..links_start[k + 1]` (`free + 1` entries).
    pub links_start: Vec<u32>,
    /// Per link: the other end (internal index).
    pub link_other: Vec<u32>,
    /// Per link: rest length (m), Hooke constant k (N/m), viscosity c (N·s/m) (eq. 3.23–3.24).
    pub link_params: Vec<[f32; 3]>,
    /// Per free mass: the root of its restoring link (eq. 3.37) or [`NO_LINK`].
    pub restoring_parent: Vec<u32>,
    /// Per free mass: the restoring link's rest direction (unit; zero without one).
    pub restoring_n: Vec<[f32; 3]>,
    /// Per free mass: the restoring link's rest length, metres (XPBD's `2w/L`).
    pub restoring_len: Vec<f32>,
    /// Per free mass: its rigid parent or [`NO_LINK`].
    pub stick_parent: Vec<u32>,
    /// Per free mass: the rigid link's length (m) and damping (N·s/m).
    pub stick: Vec<[f32; 2]>,
    /// Put masses back on their sticks after every substep (every rigid parent is anchored).
    pub project_sticks: bool,
    /// The tips, at most one per tip mass.
    pub tips: Vec<ComputeTip>,
    /// Per shell vertex its tip (index into `tips`) or [`NO_LINK`] for a bare vertex.
    pub shell_tip: Vec<u32>,
    /// Per tip: the scale vector handed to rendering and whether the guard froze it.
    pub scale: Vec<[f32; 3]>,
    /// Per tip: frozen by the guard.
    pub frozen: Vec<bool>,
    /// The guard's settings.
    pub guard: GuardSettings,
    /// XPBD's coloured links (empty for the other solvers).
    pub xpbd: ComputeXpbd,
    /// The bind pose, once the skin has been posed ([`Simulator::pose_skin`]); `None` for a
    /// static skin.
    pub pose: Option<ComputePose>,
    /// Simulated time, seconds.
    pub time_s: f64,
}

impl Simulator {
    /// This simulator's model and current state as flat arrays for a compute solver
    /// ([`ComputeModel`]). Only the explicit and stick solvers, on topologies whose rigid links
    /// and tips are rooted at anchored masses, have such a form (static or posed skin): anything else is a [`SimError::Parameter`] naming what is missing.
    pub fn compute_model(&self) -> Result<ComputeModel, SimError> {
        let m = &self.model;
        let update = match self.settings.kind {
            SolverKind::Explicit => ComputeUpdate::Explicit,
            SolverKind::Stick => ComputeUpdate::Stick,
            SolverKind::Xpbd => ComputeUpdate::Xpbd { iterations: self.settings.xpbd_iterations },
            other => {
                return Err(SimError::Parameter {
                    name: "solver",
                    what: format!("the {} solver has no compute form (explicit, stick and xpbd do)", other.name()),
                });
            }
        };
        if m.has_sticks && !m.sticks_to_anchors {
            return Err(SimError::Parameter {
                name: "topology",
                what: "rigid links between free masses have no compute form (only sticks from the skin)".into(),
            });
        }
        if !m.guard_fusable {
            return Err(SimError::Parameter {
                name: "topology",
                what: "tips whose root is a free mass have no compute form".into(),
            });
        }
        let nf = m.n_free;
        let mut seen = vec![false; m.n];
        for t in &m.tips {
            if std::mem::replace(&mut seen[t.tip as usize], true) {
                return Err(SimError::Parameter {
                    name: "topology",
                    what: "a mass is the tip of two scale vectors".into(),
                });
            }
        }
        let v3 = |v: glam::Vec3A| v.to_array();
        let xpbd = match &self.xpbd {
            Some(x) => {
                let (links, colour_start) = x.compute_links(m);
                ComputeXpbd { links, colour_start }
            }
            None => ComputeXpbd::default(),
        };
        Ok(ComputeModel {
            update,
            masses: m.n as u32,
            free: nf as u32,
            order: m.order.clone(),
            rest: m.rest.iter().copied().map(v3).collect(),
            positions: self.x.iter().copied().map(v3).collect(),
            velocities: self.v.iter().copied().map(v3).collect(),
            mass: m.mass[..nf].to_vec(),
            links_start: m.adj_start.clone(),
            link_other: m.adj.iter().map(|a| a.other).collect(),
            link_params: m.adj.iter().map(|a| [a.rest, a.k, a.c]).collect(),
            restoring_parent: m.rest_parent[..nf].to_vec(),
            restoring_n: m.rest_n[..nf].iter().copied().map(v3).collect(),
            restoring_len: m.rest_len[..nf].to_vec(),
            stick_parent: m.parent[..nf].to_vec(),
            stick: (0..nf).map(|k| [m.parent_len[k], m.parent_c[k]]).collect(),
            project_sticks: m.has_sticks,
            tips: m.tips.iter().map(|t| ComputeTip { root: t.root, tip: t.tip, n: t.n.to_array() }).collect(),
            shell_tip: m.shell_tip.clone(),
            scale: self.guard.scale.iter().copied().map(v3).collect(),
            frozen: self.guard.frozen.clone(),
            guard: self.settings.guard.clone(),
            xpbd,
            pose: self.bind.as_ref().map(|b| b.compute_form(m)),
            time_s: self.time_s,
        })
    }
}

impl ComputeModel {
    /// Checks that the arrays agree with each other and every index is in range, so that a
    /// compute solver can trust them.
    pub fn validate(&self) -> Result<(), SimError> {
        let (n, nf) = (self.masses as usize, self.free as usize);
        let bad = |what: String| Err(SimError::InvalidInput(format!("compute model: {what}")));
        if nf > n
            || self.order.len() != n
            || self.rest.len() != n
            || self.positions.len() != n
            || self.velocities.len() != n
            || self.mass.len() != nf
            || self.links_start.len() != nf + 1
            || self.restoring_parent.len() != nf
            || self.restoring_n.len() != nf
            || self.restoring_len.len() != nf
            || self.stick_parent.len() != nf
            || self.stick.len() != nf
            || self.scale.len() != self.tips.len()
            || self.frozen.len() != self.tips.len()
        {
            return bad("array lengths disagree".into());
        }
        let links = self.link_other.len();
        if self.link_params.len() != links
            || self.links_start.windows(2).any(|w| w[0] > w[1])
            || self.links_start.last().is_some_and(|&e| e as usize != links)
            || self.links_start[0] != 0
        {
            return bad("link ranges disagree with the link arrays".into());
        }
        let index = |i: u32, optional: bool| (optional && i == NO_LINK) || (i as usize) < n;
        if !self.link_other.iter().all(|&i| index(i, false))
            || !self.restoring_parent.iter().all(|&i| index(i, true))
            || !self.stick_parent.iter().all(|&i| i == NO_LINK || (i as usize >= nf && (i as usize) < n))
            || !self.tips.iter().all(|t| (t.root as usize) >= nf && (t.root as usize) < n && (t.tip as usize) < nf)
            || !self.shell_tip.iter().all(|&s| s == NO_LINK || (s as usize) < self.tips.len())
        {
            return bad("an index is out of range".into());
        }
        let colours = &self.xpbd.colour_start;
        if matches!(self.update, ComputeUpdate::Xpbd { .. })
            && (colours.first() != Some(&0)
                || colours.windows(2).any(|w| w[0] > w[1])
                || colours.last().is_some_and(|&e| e as usize != self.xpbd.links.len())
                || !self.xpbd.links.iter().all(|l| (l.ends[0] as usize) < nf && (l.ends[1] as usize) < n))
        {
            return bad("XPBD's links disagree with their colours or the masses".into());
        }
        if matches!(self.update, ComputeUpdate::Xpbd { .. })
            && !self.xpbd.links.iter().all(|l| (l.entry as usize) < links)
        {
            return bad("an XPBD link's entry is out of range".into());
        }
        if let Some(p) = &self.pose {
            let shell = self.shell_tip.len();
            if p.attach.len() != n
                || p.bind_rest.len() != n
                || p.bind_restoring_n.len() != nf
                || p.bind_tip_n.len() != self.tips.len()
            {
                return bad("the bind pose's array lengths disagree".into());
            }
            if !p.attach.iter().all(|&s| s == NO_LINK || (s as usize) < shell)
                || !p.between.iter().all(|b| {
                    b.ends.iter().all(|&e| (e as usize) < n)
                        && b.entries.iter().all(|&e| e == NO_LINK || (e as usize) < links)
                })
            {
                return bad("an index of the bind pose is out of range".into());
            }
        }
        Ok(())
    }

    /// Positions in the topology's mass order (as [`Simulator::positions`]) from per-mass
    /// positions in internal order.
    pub fn to_topology_order(&self, internal: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let mut out = vec![[0.0; 3]; internal.len()];
        for (k, &i) in self.order.iter().enumerate() {
            if let (Some(o), Some(p)) = (out.get_mut(i as usize), internal.get(k)) {
                *o = *p;
            }
        }
        out
    }
}
