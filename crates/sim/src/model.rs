//! The solver-ready form of a [`SpringTopology`] (fur thesis §3.4.1): masses reordered so that
//! the free masses come first (sorted by depth from the skin, so stick projection can run level by
//! level) and anchored ones last; per free mass a compressed adjacency of its force links
//! (springs, and the damping of sticks; eq. 3.23–3.24), its rigid parent link if any, and its
//! restoring-force data (eq. 3.37); the tips of the shell's scale vectors (eq. 3.35); and the same
//! adjacency in lane groups of eight masses ([`GroupData`], `groups.rs`) for the vectorised
//! kernels. Every solver gathers forces per mass from this adjacency, so results never depend on
//! the thread count.
//!
//! [`SimModel::new`] is the table of contents: it checks the topology and finds its hair forest
//! ([`LinkGraph`]), then runs one verb-first stage per part of the model, each reading the
//! [`ModelContext`] (graph, internal order, solver choice) and returning its own arrays.

use furbake_formats::sections::spring_topology::{NO_MASS, SpringTopology};
use glam::Vec3A;

use crate::SimError;
use crate::groups::{GROUP, GroupData, Slot};
use crate::link_graph::LinkGraph;
use crate::sentinel::NONE;

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
    /// `adj[e].other` alone (the reference solver's matrix product reads nothing else of `adj`).
    pub adj_other: Vec<u32>,
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
    /// Bumped whenever link rest lengths change ([`SimModel::set_adj_rest`]), so solvers that
    /// copy them know to copy again.
    pub rest_version: u64,
    pub spring_count: usize,
    pub stick_count: usize,
}

impl SimModel {
    /// Sets the rest length of adjacency entry `e` of free mass `k`, in the adjacency and in the
    /// lane groups that mirror it (the caller bumps `rest_version` once it is done).
    pub fn set_adj_rest(&mut self, k: usize, e: usize, rest: f32) {
        self.adj[e].rest = rest;
        let slot = self.groups.start[k / GROUP] as usize + (e - self.adj_start[k] as usize);
        self.groups.slots[slot].rest[k % GROUP] = rest;
    }

    /// Builds the model. With `springs_as_sticks` (the stick solver), every spring from an
    /// anchored root to its free child becomes a rigid stick of its rest length (orientation
    /// only, thesis §3.4.1). Springs between free masses (chain segments above the first, prism
    /// edges) stay springs: chaining rigid projections follow-the-leader style lets a chain gain
    /// energy, because a parent never feels its child.
    pub fn new(t: &SpringTopology, springs_as_sticks: bool) -> Result<SimModel, SimError> {
        let graph = LinkGraph::build(t)?;
        let order = order_by_depth(&graph);
        let cx = ModelContext { graph, order, springs_as_sticks };
        let adjacency = build_adjacency(&cx);
        let tree_children = collect_tree_children(&cx, &adjacency.tree_parent);
        let shell_tips = map_shell_tips(&cx)?;
        let restoring = build_restoring_links(&cx, &shell_tips);
        let tips = order_tips_by_mass(&cx, shell_tips);
        let springs = list_energy_springs(&cx);
        let shortest_link = find_shortest_links(&cx, &adjacency);

        let ModelContext { graph, order, .. } = cx;
        let (n, n_free) = (graph.len(), order.n_free);
        let rest = order.order.iter().map(|&i| Vec3A::from(t.mass_rest_positions[i as usize])).collect();
        let mass = order.order.iter().map(|&i| t.mass_kg[i as usize]).collect();
        let Adjacency {
            start: adj_start,
            adj,
            weight: adj_weight,
            link: _,
            tree_parent,
            tree_parent_adj,
            parent,
            parent_len,
            parent_c,
        } = adjacency;
        let mut model = SimModel {
            n,
            n_free,
            order: order.order,
            rest,
            mass,
            adj_other: adj.iter().map(|a| a.other).collect(),
            adj_start,
            adj,
            adj_weight,
            has_sticks: parent.iter().any(|&p| p != NONE),
            sticks_to_anchors: parent.iter().all(|&p| p == NONE || p as usize >= n_free),
            parent,
            parent_len,
            parent_c,
            tree_parent,
            tree_parent_adj,
            tree_children_start: tree_children.start,
            tree_children: tree_children.children,
            levels: order.levels,
            rest_parent: restoring.parent,
            rest_n: restoring.n,
            rest_len: restoring.len,
            tips: tips.tips,
            tip_first: tips.first,
            guard_fusable: tips.guard_fusable,
            shell_tip: tips.shell_tip,
            shortest_link,
            groups: GroupData::default(),
            springs,
            rest_version: 0,
            spring_count: t.spring_ends.len(),
            stick_count: t.stick_ends.len(),
        };
        // The lane groups are the finished model's per-mass data in another layout.
        model.groups = lay_out_groups(&model);
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

/// What every stage after ordering reads: the checked topology's link graph, the internal order
/// of its masses and the solver's choice of rigid links.
struct ModelContext<'t> {
    graph: LinkGraph<'t>,
    order: MassOrder,
    /// The stick solver: springs from an anchored root to its free child are rigid.
    springs_as_sticks: bool,
}

impl ModelContext<'_> {
    fn topo(&self) -> &SpringTopology {
        self.graph.topo
    }
    fn n_free(&self) -> usize {
        self.order.n_free
    }
}

/// The internal order: free masses by (depth, index), then anchored masses by index.
struct MassOrder {
    /// internal index → topology index
    order: Vec<u32>,
    /// topology index → internal index
    inv: Vec<u32>,
    n_free: usize,
    /// Free-mass ranges of equal depth, in increasing depth.
    levels: Vec<(usize, usize)>,
}

/// Orders the masses by depth from the skin (free first, anchored last) and finds the levels.
fn order_by_depth(graph: &LinkGraph) -> MassOrder {
    let (n, depth) = (graph.len(), &graph.depth);
    let mut order: Vec<u32> = (0..n as u32).collect();
    order.sort_by_key(|&i| (graph.anchored(i as usize), depth[i as usize], i));
    let n_free = order.iter().take_while(|&&i| !graph.anchored(i as usize)).count();
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
    MassOrder { order, inv, n_free, levels }
}

/// Per free mass: its force links (CSR), rigid parent and free parent in the hair tree.
struct Adjacency {
    /// Adjacency of free mass `k`: `adj[start[k]..start[k + 1]]`.
    start: Vec<u32>,
    adj: Vec<Adj>,
    /// Per entry: the link's weight on the implicit diagonal (see `SimModel::adj_weight`).
    weight: Vec<f32>,
    /// Per entry: the link (index into `LinkGraph::links`).
    link: Vec<u32>,
    tree_parent: Vec<u32>,
    tree_parent_adj: Vec<u32>,
    parent: Vec<u32>,
    parent_len: Vec<f32>,
    parent_c: Vec<f32>,
}

/// Builds each free mass's adjacency and finds its rigid and tree parents. Which links are rigid:
/// sticks always; with `springs_as_sticks` also every root spring. Mass–spring solvers keep a
/// stick's damping as a force on both ends; the stick solver applies a rigid link's damping to
/// the child only (see `stick.rs`), so there a rigid link is no adjacency entry.
fn build_adjacency(cx: &ModelContext) -> Adjacency {
    let (g, n_free, inv) = (&cx.graph, cx.n_free(), &cx.order.inv);
    let mut a = Adjacency {
        start: vec![0u32; n_free + 1],
        adj: Vec::new(),
        weight: Vec::new(),
        link: Vec::new(),
        tree_parent: vec![NONE; n_free],
        tree_parent_adj: vec![NONE; n_free],
        parent: vec![NONE; n_free],
        parent_len: vec![0.0; n_free],
        parent_c: vec![0.0; n_free],
    };
    for k in 0..n_free {
        let i = cx.order.order[k] as usize;
        for &li in g.incident(i) {
            let l = g.links[li as usize];
            let j = l.other_end(i);
            let parent_of_i = g.parent_link[i] == li;
            let rigid = l.stick || (cx.springs_as_sticks && parent_of_i && g.anchored(j));
            if rigid && parent_of_i {
                a.parent[k] = inv[j];
                a.parent_len[k] = l.rest;
                a.parent_c[k] = l.c;
            }
            if !(rigid && cx.springs_as_sticks) {
                let other_free = !g.anchored(j);
                let tree = other_free && (parent_of_i || g.parent_link[j] == li);
                if tree && parent_of_i {
                    a.tree_parent[k] = inv[j];
                    a.tree_parent_adj[k] = a.adj.len() as u32;
                }
                a.weight.push(if other_free && !tree { 2.0 } else { 1.0 });
                a.adj.push(Adj { other: inv[j], rest: l.rest, k: if l.stick { 0.0 } else { l.k }, c: l.c });
                a.link.push(li);
            }
        }
        a.start[k + 1] = a.adj.len() as u32;
    }
    a
}

/// CSR of tree children per free mass.
struct TreeChildren {
    start: Vec<u32>,
    children: Vec<u32>,
}

/// Inverts the free parents of the hair tree into children lists.
fn collect_tree_children(cx: &ModelContext, tree_parent: &[u32]) -> TreeChildren {
    let n_free = cx.n_free();
    let mut start = vec![0u32; n_free + 1];
    for &p in tree_parent {
        if p != NONE {
            start[p as usize + 1] += 1;
        }
    }
    for k in 0..n_free {
        start[k + 1] += start[k];
    }
    let mut fill = start.clone();
    let mut children = vec![0u32; start[n_free] as usize];
    for (k, &p) in tree_parent.iter().enumerate() {
        if p != NONE {
            children[fill[p as usize] as usize] = k as u32;
            fill[p as usize] += 1;
        }
    }
    TreeChildren { start, children }
}

/// The tips named by the shell-vertex map, in order of first mention.
struct ShellTips {
    tips: Vec<Tip>,
    /// Per topology mass: its slot in `tips` (NONE when it is no tip).
    tip_slot: Vec<u32>,
    /// Per shell vertex: its slot in `tips` (NONE for bare vertices).
    shell_tip: Vec<u32>,
}

/// Tips (eq. 3.35): one per distinct tip mass named by the shell-vertex map; its rest direction
/// runs from root to tip.
fn map_shell_tips(cx: &ModelContext) -> Result<ShellTips, SimError> {
    let (t, n, inv) = (cx.topo(), cx.graph.len(), &cx.order.inv);
    let bad = |what: String| Err(SimError::InvalidInput(what));
    let mut m = ShellTips {
        tips: Vec::new(),
        tip_slot: vec![NONE; n],
        shell_tip: Vec::with_capacity(t.shell_vertex_masses.len()),
    };
    for &[r, tp] in &t.shell_vertex_masses {
        if r == NO_MASS {
            m.shell_tip.push(NONE);
            continue;
        }
        if r as usize >= n || tp as usize >= n || r == tp {
            return bad(format!("shell vertex maps to masses ({r}, {tp}) outside the topology"));
        }
        if cx.graph.anchored(tp as usize) {
            return bad(format!("shell vertex tip mass {tp} is anchored"));
        }
        if m.tip_slot[tp as usize] == NONE {
            let (pr, pt) =
                (Vec3A::from(t.mass_rest_positions[r as usize]), Vec3A::from(t.mass_rest_positions[tp as usize]));
            let nrm = (pt - pr).try_normalize().unwrap_or(Vec3A::Y);
            m.tip_slot[tp as usize] = m.tips.len() as u32;
            m.tips.push(Tip { root: inv[r as usize], tip: inv[tp as usize], n: nrm });
        }
        m.shell_tip.push(m.tip_slot[tp as usize]);
    }
    Ok(m)
}

/// Per free mass: the restoring link of eq. 3.37 (parent, rest direction, rest length).
struct RestoringLinks {
    parent: Vec<u32>,
    n: Vec<Vec3A>,
    len: Vec<f32>,
}

/// Restoring links (eq. 3.37): every free mass is pulled towards the rest direction of its
/// parent link (for two-mass topologies the parent is the root, exactly eq. 3.37; along a chain
/// every segment is restored, so a folded chain cannot stay folded). A zero-length link takes its
/// tip's direction, else +Y.
fn build_restoring_links(cx: &ModelContext, shell: &ShellTips) -> RestoringLinks {
    let (t, g, n_free, inv) = (cx.topo(), &cx.graph, cx.n_free(), &cx.order.inv);
    let mut r = RestoringLinks { parent: vec![NONE; n_free], n: vec![Vec3A::ZERO; n_free], len: vec![0.0; n_free] };
    for k in 0..n_free {
        let i = cx.order.order[k] as usize;
        let li = g.parent_link[i];
        if li == NONE {
            continue;
        }
        let j = g.links[li as usize].other_end(i);
        let (pj, pi) = (Vec3A::from(t.mass_rest_positions[j]), Vec3A::from(t.mass_rest_positions[i]));
        let fallback = if shell.tip_slot[i] != NONE { shell.tips[shell.tip_slot[i] as usize].n } else { Vec3A::Y };
        r.parent[k] = inv[j];
        r.n[k] = (pi - pj).try_normalize().unwrap_or(fallback);
        r.len[k] = pi.distance(pj);
    }
    r
}

/// The tips in the order of their tip masses (see `SimModel::tips`).
struct OrderedTips {
    tips: Vec<Tip>,
    shell_tip: Vec<u32>,
    first: Vec<u32>,
    guard_fusable: bool,
}

/// Sorts the tips by tip mass, so a range of free masses owns a range of tips, and renumbers the
/// shell vertices' tip slots to match.
fn order_tips_by_mass(cx: &ModelContext, shell: ShellTips) -> OrderedTips {
    let n_free = cx.n_free();
    let ShellTips { tips, mut shell_tip, .. } = shell;
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
    let mut first = vec![0u32; n_free + 1];
    for t in &tips {
        first[t.tip as usize + 1] += 1;
    }
    for k in 0..n_free {
        first[k + 1] += first[k];
    }
    let guard_fusable = tips.iter().all(|t| t.root as usize >= n_free);
    OrderedTips { tips, shell_tip, first, guard_fusable }
}

/// The springs that act as springs in this model, internal indices, with rest length and
/// stiffness (energy). Springs that the stick solver made rigid hold no energy there.
fn list_energy_springs(cx: &ModelContext) -> Vec<([u32; 2], f32, f32)> {
    let (t, g, inv) = (cx.topo(), &cx.graph, &cx.order.inv);
    let rigid_spring = |s: usize| {
        cx.springs_as_sticks && {
            let [a, b] = t.spring_ends[s];
            (g.parent_link[a as usize] == s as u32 && g.anchored(b as usize))
                || (g.parent_link[b as usize] == s as u32 && g.anchored(a as usize))
        }
    };
    (0..t.spring_ends.len())
        .filter(|&s| !rigid_spring(s))
        .map(|s| {
            let [a, b] = t.spring_ends[s];
            ([inv[a as usize], inv[b as usize]], t.spring_rest_lengths_m[s], t.spring_stiffness_n_per_m[s])
        })
        .collect()
}

/// Per free mass: its shortest non-zero link length (force links and rigid parent), metres;
/// infinity when it has none.
fn find_shortest_links(cx: &ModelContext, a: &Adjacency) -> Vec<f32> {
    (0..cx.n_free())
        .map(|k| {
            let adj_min = a.adj[a.start[k] as usize..a.start[k + 1] as usize]
                .iter()
                .map(|a| a.rest)
                .filter(|&r| r > 0.0)
                .fold(f32::INFINITY, f32::min);
            if a.parent_len[k] > 0.0 { adj_min.min(a.parent_len[k]) } else { adj_min }
        })
        .collect()
}

/// Lays out `model`'s free masses in lane groups (`groups.rs`; its `groups` field is not read).
fn lay_out_groups(model: &SimModel) -> GroupData {
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
