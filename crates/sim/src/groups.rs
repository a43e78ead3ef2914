//! The lane-group layout of the free masses: the model's per-mass data regrouped so that eight
//! consecutive free masses fill the eight `f32` lanes of one AVX register. The explicit
//! (fur thesis eq. 3.20–3.25), stick (§3.3.2) and one-sweep implicit (eq. 3.26–3.34) kernels
//! gather each mass's link forces slot by slot from here, together with its restoring link
//! (eq. 3.37), rigid parent and tip (the wrong-side guard of §3.4.3, eq. 3.35).
//!
//! The layout is derived from a finished `SimModel` (`lay_out_groups`, the last stage of
//! `SimModel::new` in `model.rs`) and holds nothing the model does not: it is the same data in a
//! different order, padded to whole groups.

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
