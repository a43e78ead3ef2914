//! The solver-ready form of a [`SpringTopology`]: masses reordered so that the free masses come
//! first (sorted by depth from the skin, so stick projection can run level by level) and anchored
//! ones last; per free mass a compressed adjacency of its force links (springs, and the damping of
//! sticks), its rigid parent link if any, and its restoring-force data (eq. 3.37); and the same
//! adjacency in lane groups of eight masses ([`GroupData`], `groups.rs`) for the vectorised kernels. Every
//! solver gathers forces per mass from this adjacency, so results never depend on the thread
//! count.
//!
//! The topology was validated when it was decoded or built; [`SimModel::new`] re-checks the few
//! structural assumptions the solvers make and reports violations as [`SimError::InvalidInput`].

use std::collections::VecDeque;

use furbake_formats::sections::spring_topology::{NO_MASS, SpringTopology};
use glam::Vec3A;

use crate::SimError;
use crate::groups::GroupData;

/// Marks "none" in the per-mass `u32` tables.
pub(crate) const NONE: u32 = u32::MAX;

/// One force link seen from a free mass: the other end (internal index), rest length, Hooke and
/// viscosity constants (eq. 3.23–3.24).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub(crate) struct Adj {
    pub other: u32,
    pub rest: f32,
    pub k: f32,
    pub c: f32,
}

/// One tip: the mass whose direction from its root gives a scale vector (eq. 3.35).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tip {
    pub root: u32,
    pub tip: u32,
    /// Rest direction = vertex normal, unit.
    pub n: Vec3A,
}

#[derive(Debug)]
pub(crate) struct SimModel {
    pub n: usize,
    pub n_free: usize,
    /// internal index → topology index
    pub order: Vec<u32>,
    pub rest: Vec<Vec3A>,
    pub mass: Vec<f32>,
    /// CSR over free masses: adjacency of free mass i is `adj[adj_start[i]..adj_start[i + 1]]`.
    pub adj_start: Vec<u32>,
    pub adj: Vec<Adj>,
    /// `adj[e].other` alone (the reference solver's matrix product reads nothing else).
    pub adj_other: Vec<u32>,
    /// Per adjacency entry of a link between two free masses: the link's slot among those links
    /// (numbered in the order their first end lists them; NONE for links to anchored masses),
    /// and whether this entry is that first listing. Per free mass `k`: the first slot it lists
    /// first (`ref_first[k]..ref_first[k + 1]`). The reference solver stores one block per slot.
    pub ref_slot: Vec<u32>,
    pub ref_owner: Vec<bool>,
    pub ref_first: Vec<u32>,
    /// Per free mass: the rigid parent (internal index) or NONE, its length and damping.
    pub parent: Vec<u32>,
    pub parent_len: Vec<f32>,
    pub parent_c: Vec<f32>,
    /// Per adjacency entry: how often the link counts on the implicit solver's diagonal — 1 for
    /// links to anchored masses and for tree links (a free mass's link to its free parent, solved
    /// exactly by elimination along the hair), 2 for the other links between free masses.
    pub adj_weight: Vec<f32>,
    /// Per free mass: its free parent in the hair tree (NONE when the parent is anchored or
    /// absent) and the index in `adj` of its entry for that link.
    pub tree_parent: Vec<u32>,
    pub tree_parent_adj: Vec<u32>,
    /// CSR of tree children per free mass.
    pub tree_children_start: Vec<u32>,
    pub tree_children: Vec<u32>,
    /// True when some free mass has a rigid parent link (stick projection needed).
    pub has_sticks: bool,
    /// Free-mass ranges of equal depth, in increasing depth (stick projection order).
    pub levels: Vec<(usize, usize)>,
    /// Per free mass: the parent of its restoring link (eq. 3.37) or NONE, the link's rest
    /// direction and rest length.
    pub rest_parent: Vec<u32>,
    pub rest_n: Vec<Vec3A>,
    pub rest_len: Vec<f32>,
    /// Distinct tips in the order of their tip masses, and per shell vertex its tip slot (NONE
    /// for bare vertices).
    pub tips: Vec<Tip>,
    /// Per free mass `k`: the tips whose tip mass comes before `k` (so masses `a..b` own tips
    /// `tip_first[a]..tip_first[b]`).
    pub tip_first: Vec<u32>,
    /// True when every tip's root is anchored: the guard can test a tip as soon as it has moved.
    pub guard_fusable: bool,
    pub shell_tip: Vec<u32>,
    /// Per free mass: its shortest non-zero link length, metres (infinity when it has none).
    pub shortest_link: Vec<f32>,
    /// The per-mass lane-group layout of the explicit, stick and one-sweep implicit kernels.
    pub groups: GroupData,
    /// True when every rigid parent link ends at an anchored mass, so a mass can be projected on
    /// its stick as soon as it has moved (no level-by-level pass).
    pub sticks_to_anchors: bool,
    /// The springs that act as springs in this model, internal indices (energy).
    pub springs: Vec<([u32; 2], f32, f32)>,
    pub spring_count: usize,
    pub stick_count: usize,
}

impl SimModel {
    /// Builds the model. With `springs_as_sticks` (the stick solver), every spring from an
    /// anchored root to its free child becomes a rigid stick of its rest length (orientation
    /// only, thesis §3.4.1). Springs between free masses (chain segments above the first, prism
    /// edges) stay springs: chaining rigid projections follow-the-leader style lets a chain gain
    /// energy, because a parent never feels its child.
    pub fn new(t: &SpringTopology, springs_as_sticks: bool) -> Result<SimModel, SimError> {
        let n = t.mass_kg.len();
        let bad = |what: String| Err(SimError::InvalidInput(what));
        let lens = [
            t.mass_rest_positions.len(),
            t.mass_anchored.len(),
            t.spring_ends.len(),
            t.spring_rest_lengths_m.len(),
            t.spring_stiffness_n_per_m.len(),
            t.spring_damping_n_s_per_m.len(),
            t.stick_ends.len(),
            t.stick_lengths_m.len(),
        ];
        if lens[0] != n
            || lens[1] != n
            || lens[3] != lens[2]
            || lens[4] != lens[2]
            || lens[5] != lens[2]
            || lens[7] != lens[6]
        {
            return bad(format!("topology arrays disagree in length: {n} masses, {lens:?}"));
        }
        if n >= NONE as usize {
            return bad("too many masses".into());
        }
        let in_range = |e: &[u32; 2]| (e[0] as usize) < n && (e[1] as usize) < n && e[0] != e[1];
        if !t.spring_ends.iter().all(in_range) || !t.stick_ends.iter().all(in_range) {
            return bad("a spring or stick index is out of range or joins a mass to itself".into());
        }
        if !t.mass_kg.iter().all(|m| m.is_finite() && *m > 0.0)
            || !t.mass_rest_positions.iter().flatten().all(|c| c.is_finite())
        {
            return bad("masses must be positive and positions finite".into());
        }
        let anchored = |i: usize| t.mass_anchored[i] != 0;
        let damping = t.params.damping_n_s_per_m;

        // Undirected link list: (a, b, rest, k, c, is_stick), topology order, springs then sticks.
        let mut links: Vec<(u32, u32, f32, f32, f32, bool)> = Vec::with_capacity(lens[2] + lens[6]);
        for s in 0..lens[2] {
            let [a, b] = t.spring_ends[s];
            links.push((
                a,
                b,
                t.spring_rest_lengths_m[s],
                t.spring_stiffness_n_per_m[s],
                t.spring_damping_n_s_per_m[s],
                false,
            ));
        }
        for s in 0..lens[6] {
            let [a, b] = t.stick_ends[s];
            links.push((a, b, t.stick_lengths_m[s], 0.0, damping, true));
        }
        if links
            .iter()
            .any(|l| !(l.2.is_finite() && l.3.is_finite() && l.4.is_finite() && l.2 >= 0.0 && l.3 >= 0.0 && l.4 >= 0.0))
        {
            return bad("link lengths and constants must be finite and ≥ 0".into());
        }
        let mut inc_start = vec![0u32; n + 1];
        for l in &links {
            inc_start[l.0 as usize + 1] += 1;
            inc_start[l.1 as usize + 1] += 1;
        }
        for i in 0..n {
            inc_start[i + 1] += inc_start[i];
        }
        let mut fill = inc_start.clone();
        let mut inc = vec![0u32; inc_start[n] as usize];
        for (li, l) in links.iter().enumerate() {
            for e in [l.0, l.1] {
                inc[fill[e as usize] as usize] = li as u32;
                fill[e as usize] += 1;
            }
        }
        let incident = |i: usize| &inc[inc_start[i] as usize..inc_start[i + 1] as usize];

        // Breadth-first search from the anchored masses: depth and parent link of every mass.
        // A mass that is the far end of a stick takes that stick as its parent.
        let mut depth = vec![u32::MAX; n];
        let mut parent_link = vec![NONE; n];
        let mut queue = VecDeque::new();
        for (i, d) in depth.iter_mut().enumerate() {
            if anchored(i) {
                *d = 0;
                queue.push_back(i);
            }
        }
        let mut stick_child = vec![NONE; n];
        for (li, l) in links.iter().enumerate() {
            if l.5 {
                if anchored(l.1 as usize) || stick_child[l.1 as usize] != NONE {
                    return bad(format!("mass {} is the far end of an anchored or second stick", l.1));
                }
                stick_child[l.1 as usize] = li as u32;
            }
        }
        while let Some(i) = queue.pop_front() {
            for &li in incident(i) {
                let l = links[li as usize];
                let j = if l.0 as usize == i { l.1 } else { l.0 } as usize;
                if depth[j] != u32::MAX {
                    continue;
                }
                // Sticks are only ever followed from their near end.
                if l.5 && l.1 as usize != j {
                    continue;
                }
                depth[j] = depth[i] + 1;
                parent_link[j] = li;
                queue.push_back(j);
            }
        }
        for (i, &stick) in stick_child.iter().enumerate() {
            if stick != NONE && parent_link[i] != stick {
                return bad(format!("stick {stick} does not lead away from the skin"));
            }
        }
        for d in &mut depth {
            if *d == u32::MAX {
                *d = 1; // a free mass not connected to the skin: it floats.
            }
        }

        // Internal order: free masses by (depth, index), then anchored masses by index.
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.sort_by_key(|&i| (anchored(i as usize), depth[i as usize], i));
        let n_free = order.iter().take_while(|&&i| !anchored(i as usize)).count();
        let mut inv = vec![0u32; n];
        for (k, &i) in order.iter().enumerate() {
            inv[i as usize] = k as u32;
        }
        let mut levels = Vec::new();
        let mut s = 0;
        while s < n_free {
            let d = depth[order[s] as usize];
            let mut e = s;
            while e < n_free && depth[order[e] as usize] == d {
                e += 1;
            }
            levels.push((s, e));
            s = e;
        }

        // Which links are rigid: sticks always; with `springs_as_sticks` also every root spring.
        // Mass–spring solvers keep a stick's damping as a force on both ends; the stick solver
        // applies a rigid link's damping to the child only (see `stick.rs`).
        let mut adj_start = vec![0u32; n_free + 1];
        let mut adj = Vec::new();
        let mut adj_weight = Vec::new();
        let mut adj_link: Vec<u32> = Vec::new();
        let mut tree_parent = vec![NONE; n_free];
        let mut tree_parent_adj = vec![NONE; n_free];
        let mut parent = vec![NONE; n_free];
        let mut parent_len = vec![0.0; n_free];
        let mut parent_c = vec![0.0; n_free];
        for k in 0..n_free {
            let i = order[k] as usize;
            for &li in incident(i) {
                let l = links[li as usize];
                let j = if l.0 as usize == i { l.1 } else { l.0 } as usize;
                let parent_of_i = parent_link[i] == li;
                let rigid = l.5 || (springs_as_sticks && parent_of_i && anchored(j));
                if rigid && parent_of_i {
                    parent[k] = inv[j];
                    parent_len[k] = l.2;
                    parent_c[k] = l.4;
                }
                if !(rigid && springs_as_sticks) {
                    let other_free = !anchored(j);
                    let tree = other_free && (parent_of_i || parent_link[j] == li);
                    if tree && parent_of_i {
                        tree_parent[k] = inv[j];
                        tree_parent_adj[k] = adj.len() as u32;
                    }
                    adj_weight.push(if other_free && !tree { 2.0 } else { 1.0 });
                    adj.push(Adj { other: inv[j], rest: l.2, k: if l.5 { 0.0 } else { l.3 }, c: l.4 });
                    adj_link.push(li);
                }
            }
            adj_start[k + 1] = adj.len() as u32;
        }
        // Links between free masses, numbered in the order their first end lists them.
        let mut ref_slot = vec![NONE; adj.len()];
        let mut ref_owner = vec![false; adj.len()];
        let mut ref_first = vec![0u32; n_free + 1];
        let mut slot_of_link = vec![NONE; links.len()];
        let mut slots = 0u32;
        for k in 0..n_free {
            for e in adj_start[k] as usize..adj_start[k + 1] as usize {
                if adj[e].other as usize >= n_free {
                    continue;
                }
                let li = adj_link[e] as usize;
                if slot_of_link[li] == NONE {
                    slot_of_link[li] = slots;
                    slots += 1;
                    ref_owner[e] = true;
                }
                ref_slot[e] = slot_of_link[li];
            }
            ref_first[k + 1] = slots;
        }

        // Tips (eq. 3.35): one per distinct tip mass named by the shell-vertex map.
        let mut tip_slot = vec![NONE; n];
        let mut tips = Vec::new();
        let mut shell_tip = Vec::with_capacity(t.shell_vertex_masses.len());
        for &[r, tp] in &t.shell_vertex_masses {
            if r == NO_MASS {
                shell_tip.push(NONE);
                continue;
            }
            if r as usize >= n || tp as usize >= n || r == tp {
                return bad(format!("shell vertex maps to masses ({r}, {tp}) outside the topology"));
            }
            if anchored(tp as usize) {
                return bad(format!("shell vertex tip mass {tp} is anchored"));
            }
            if tip_slot[tp as usize] == NONE {
                let (pr, pt) =
                    (Vec3A::from(t.mass_rest_positions[r as usize]), Vec3A::from(t.mass_rest_positions[tp as usize]));
                let nrm = (pt - pr).try_normalize().unwrap_or(Vec3A::Y);
                tip_slot[tp as usize] = tips.len() as u32;
                tips.push(Tip { root: inv[r as usize], tip: inv[tp as usize], n: nrm });
            }
            shell_tip.push(tip_slot[tp as usize]);
        }
        let mut tree_children_start = vec![0u32; n_free + 1];
        for &p in &tree_parent {
            if p != NONE {
                tree_children_start[p as usize + 1] += 1;
            }
        }
        for k in 0..n_free {
            tree_children_start[k + 1] += tree_children_start[k];
        }
        let mut fill = tree_children_start.clone();
        let mut tree_children = vec![0u32; tree_children_start[n_free] as usize];
        for (k, &p) in tree_parent.iter().enumerate() {
            if p != NONE {
                tree_children[fill[p as usize] as usize] = k as u32;
                fill[p as usize] += 1;
            }
        }

        // Restoring links (eq. 3.37): every free mass is pulled towards the rest direction of its
        // parent link (for two-mass topologies the parent is the root, exactly eq. 3.37; along a
        // chain every segment is restored, so a folded chain cannot stay folded).
        let mut rest_parent = vec![NONE; n_free];
        let mut rest_n = vec![Vec3A::ZERO; n_free];
        let mut rest_len = vec![0.0; n_free];
        for k in 0..n_free {
            let i = order[k] as usize;
            let li = parent_link[i];
            if li == NONE {
                continue;
            }
            let l = links[li as usize];
            let j = if l.0 as usize == i { l.1 } else { l.0 } as usize;
            let (pj, pi) = (Vec3A::from(t.mass_rest_positions[j]), Vec3A::from(t.mass_rest_positions[i]));
            let fallback = if tip_slot[i] != NONE { tips[tip_slot[i] as usize].n } else { Vec3A::Y };
            rest_parent[k] = inv[j];
            rest_n[k] = (pi - pj).try_normalize().unwrap_or(fallback);
            rest_len[k] = pi.distance(pj);
        }

        // Tips in the order of their tip masses, so a range of free masses owns a range of tips.
        let mut by_mass: Vec<u32> = (0..tips.len() as u32).collect();
        by_mass.sort_by_key(|&t| tips[t as usize].tip);
        let mut new_slot = vec![0u32; tips.len()];
        for (ns, &old) in by_mass.iter().enumerate() {
            new_slot[old as usize] = ns as u32;
        }
        let tips: Vec<Tip> = by_mass.iter().map(|&t| tips[t as usize]).collect();
        for s in &mut shell_tip {
            if *s != NONE {
                *s = new_slot[*s as usize];
            }
        }
        let mut tip_first = vec![0u32; n_free + 1];
        for t in &tips {
            tip_first[t.tip as usize + 1] += 1;
        }
        for k in 0..n_free {
            tip_first[k + 1] += tip_first[k];
        }
        let guard_fusable = tips.iter().all(|t| t.root as usize >= n_free);

        let rest: Vec<Vec3A> = order.iter().map(|&i| Vec3A::from(t.mass_rest_positions[i as usize])).collect();
        let mass: Vec<f32> = order.iter().map(|&i| t.mass_kg[i as usize]).collect();
        // Springs that the stick solver made rigid hold no energy there.
        let rigid_spring = |s: usize| {
            springs_as_sticks && {
                let [a, b] = t.spring_ends[s];
                (parent_link[a as usize] == s as u32 && anchored(b as usize))
                    || (parent_link[b as usize] == s as u32 && anchored(a as usize))
            }
        };
        let springs = (0..lens[2])
            .filter(|&s| !rigid_spring(s))
            .map(|s| {
                let [a, b] = t.spring_ends[s];
                ([inv[a as usize], inv[b as usize]], t.spring_rest_lengths_m[s], t.spring_stiffness_n_per_m[s])
            })
            .collect();
        let shortest_link: Vec<f32> = (0..n_free)
            .map(|k| {
                let adj_min = adj[adj_start[k] as usize..adj_start[k + 1] as usize]
                    .iter()
                    .map(|a| a.rest)
                    .filter(|&r| r > 0.0)
                    .fold(f32::INFINITY, f32::min);
                if parent_len[k] > 0.0 { adj_min.min(parent_len[k]) } else { adj_min }
            })
            .collect();
        let has_sticks = parent.iter().any(|&p| p != NONE);
        let sticks_to_anchors = parent.iter().all(|&p| p == NONE || p as usize >= n_free);
        let adj_other = adj.iter().map(|a| a.other).collect();
        let mut model = SimModel {
            has_sticks,
            shortest_link,
            n,
            n_free,
            order,
            rest,
            mass,
            adj_start,
            adj,
            adj_weight,
            tree_parent,
            tree_parent_adj,
            tree_children_start,
            tree_children,
            parent,
            parent_len,
            parent_c,
            levels,
            rest_parent,
            rest_n,
            rest_len,
            tips,
            tip_first,
            guard_fusable,
            shell_tip,
            adj_other,
            ref_slot,
            ref_owner,
            ref_first,
            groups: GroupData::default(),
            sticks_to_anchors,
            springs,
            spring_count: lens[2],
            stick_count: lens[6],
        };
        // The lane groups are the finished model's per-mass data in another layout.
        model.groups = GroupData::lay_out(&model);
        Ok(model)
    }

    /// True when some free mass hangs from another free mass (chains).
    pub fn has_tree(&self) -> bool {
        !self.tree_children.is_empty()
    }

    #[inline]
    pub fn adj_of(&self, k: usize) -> &[Adj] {
        &self.adj[self.adj_start[k] as usize..self.adj_start[k + 1] as usize]
    }

    /// Restoring-force stiffness used by the stability estimate and the implicit Jacobian:
    /// `2w / L` (the tangential stiffness of eq. 3.37 peaks below this), N/m. `L` is clamped at
    /// 1 mm: the force is bounded by `4w` whatever the length, so a zero-length link is not stiff.
    #[inline]
    pub fn restoring_stiffness(&self, k: usize, w: f32) -> f32 {
        if self.rest_parent[k] == NONE || w == 0.0 { 0.0 } else { 2.0 * w / self.rest_len[k].max(1e-3) }
    }
}
