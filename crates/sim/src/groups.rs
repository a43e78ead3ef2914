//! The lane-group layout of the free masses: the model's per-mass data regrouped so that eight
//! consecutive free masses fill the eight `f32` lanes of one AVX register. The explicit
//! (fur thesis eq. 3.20–3.25), stick (§3.3.2) and one-sweep implicit (eq. 3.26–3.34) kernels
//! gather each mass's link forces slot by slot from here, together with its restoring link
//! (eq. 3.37), rigid parent and tip (the wrong-side guard of §3.4.3, eq. 3.35).
//!
//! The layout is derived from a finished [`SimModel`] and holds nothing the model does not: it
//! is the same data in a different order, padded to whole groups.

use crate::model::{NONE, SimModel};

/// Free masses per lane group of the per-mass kernels (one AVX register of `f32`).
pub(crate) const GROUP: usize = 8;

/// One adjacency slot of a lane group: for each of the group's eight free masses, one of its force
/// links (the other end, rest length, Hooke and viscosity constants), in adjacency order; masses
/// with fewer links than the group's widest get a padding link to themselves with zero constants
/// (zero length, zero force, zero block). 128 bytes: two cache lines serve eight links.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Slot {
    pub other: [u32; GROUP],
    pub rest: [f32; GROUP],
    pub k: [f32; GROUP],
    pub c: [f32; GROUP],
}

/// Per-mass data of the lane groups, padded to whole groups (a padding lane repeats the last free
/// mass's index and carries no restoring link, no parent and zero constants).
#[derive(Debug, Default)]
pub(crate) struct GroupData {
    /// Slots of group `g`: `slots[start[g]..start[g + 1]]`.
    pub start: Vec<u32>,
    pub slots: Vec<Slot>,
    /// Per slot entry: the link's weight on the implicit diagonal (`adj_weight`; 0 for padding).
    pub slot_w: Vec<[f32; GROUP]>,
    /// Per lane: the free mass it computes (padding lanes: the last free mass).
    pub lane: Vec<u32>,
    pub mass: Vec<f32>,
    pub inv_mass: Vec<f32>,
    pub rest_parent: Vec<u32>,
    /// Rest direction of the restoring link, by component.
    pub rest_n: [Vec<f32>; 3],
    pub rest_len: Vec<f32>,
    pub parent: Vec<u32>,
    pub parent_len: Vec<f32>,
    pub parent_c: Vec<f32>,
    /// Shortest link per lane (infinity for padding lanes: no rotation limit).
    pub shortest_link: Vec<f32>,
    /// Per lane: the root of the tip this mass is (NONE when it is none), and the tip's rest
    /// direction by component (the wrong-side guard, run in the same pass).
    pub tip_root: Vec<u32>,
    pub tip_n: [Vec<f32>; 3],
}

impl GroupData {
    /// Lays out `model`'s free masses in lane groups (its `groups` field is not read).
    pub fn lay_out(model: &SimModel) -> GroupData {
        let mut g = GroupData::default();
        if model.n_free == 0 {
            g.start.push(0);
        } else {
            lay_out_slots(model, &mut g);
            lay_out_lanes(model, &mut g);
        }
        lay_out_tips(model, &mut g);
        g
    }
}

/// The adjacency slots of every group (`start`, `slots`, `slot_w`).
fn lay_out_slots(model: &SimModel, g: &mut GroupData) {
    let (n_free, adj_start) = (model.n_free, &model.adj_start);
    let ng = n_free.div_ceil(GROUP);
    g.start.reserve(ng + 1);
    g.start.push(0);
    for gi in 0..ng {
        let lanes: [usize; GROUP] = std::array::from_fn(|l| (gi * GROUP + l).min(n_free - 1));
        let real = |l: usize| gi * GROUP + l < n_free;
        let deg = |l: usize| if real(l) { (adj_start[lanes[l] + 1] - adj_start[lanes[l]]) as usize } else { 0 };
        let width = (0..GROUP).map(deg).max().unwrap_or(0);
        for s in 0..width {
            let mut slot = Slot { other: [0; GROUP], rest: [0.0; GROUP], k: [0.0; GROUP], c: [0.0; GROUP] };
            let mut w = [0.0; GROUP];
            for l in 0..GROUP {
                if s < deg(l) {
                    let e = adj_start[lanes[l]] as usize + s;
                    let a = model.adj[e];
                    (slot.other[l], slot.rest[l], slot.k[l], slot.c[l], w[l]) =
                        (a.other, a.rest, a.k, a.c, model.adj_weight[e]);
                } else {
                    slot.other[l] = lanes[l] as u32;
                }
            }
            g.slots.push(slot);
            g.slot_w.push(w);
        }
        g.start.push(g.slots.len() as u32);
    }
}

/// The per-lane data (mass, restoring link, rigid parent, shortest link), padded to whole groups.
fn lay_out_lanes(model: &SimModel, g: &mut GroupData) {
    let n_free = model.n_free;
    let np = n_free.div_ceil(GROUP) * GROUP;
    let real = |k: usize| k < n_free;
    let m = model;
    g.lane = (0..np).map(|k| k.min(n_free - 1) as u32).collect();
    g.mass = (0..np).map(|k| if real(k) { m.mass[k] } else { 1.0 }).collect();
    g.inv_mass = (0..np).map(|k| if real(k) { 1.0 / m.mass[k] } else { 0.0 }).collect();
    g.rest_parent = (0..np).map(|k| if real(k) { m.rest_parent[k] } else { NONE }).collect();
    g.rest_n = std::array::from_fn(|a| (0..np).map(|k| if real(k) { m.rest_n[k][a] } else { 0.0 }).collect());
    g.rest_len = (0..np).map(|k| if real(k) { m.rest_len[k] } else { 0.0 }).collect();
    g.parent = (0..np).map(|k| if real(k) { m.parent[k] } else { NONE }).collect();
    g.parent_len = (0..np).map(|k| if real(k) { m.parent_len[k] } else { 0.0 }).collect();
    g.parent_c = (0..np).map(|k| if real(k) { m.parent_c[k] } else { 0.0 }).collect();
    g.shortest_link = (0..np).map(|k| if real(k) { m.shortest_link[k] } else { f32::INFINITY }).collect();
}

/// Per lane: the root and rest direction of the tip the lane's mass is, if any.
fn lay_out_tips(model: &SimModel, g: &mut GroupData) {
    let np = g.lane.len();
    g.tip_root = vec![NONE; np];
    g.tip_n = std::array::from_fn(|_| vec![0.0; np]);
    for t in &model.tips {
        g.tip_root[t.tip as usize] = t.root;
        for a in 0..3 {
            g.tip_n[a][t.tip as usize] = t.n[a];
        }
    }
}
