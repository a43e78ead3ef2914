//! Exact implicit solves on small clusters of free masses.
//!
//! The implicit solver's Jacobi sweeps (see `solvers`) replace every link between two free masses
//! by twice its block on the diagonal. That preconditioner `P ≥ A` makes each sweep convergent,
//! but a truncated solve is backward Euler with a position-dependent "mass" `P − h²K(x)`; when a
//! stiff cluster spins (the three tips of a separable prism are a small rigid triangle hanging on
//! soft springs), that fake mass rotates with the links every step and pumps energy into the spin
//! (found by the randomised stability cases: separable prisms at `h²k/m ≫ 1` grew without bound).
//!
//! Where every connected component of the free-mass link graph is small (separable prisms:
//! three tips; separable spring–sticks: one), the linearised backward-Euler system (eq. 3.26–3.33,
//! the same system the reference solver converges) falls apart into independent dense systems of
//! at most `3 · MAX_CLUSTER` unknowns, which are solved exactly instead. The step is then the
//! exact linearised backward-Euler step for any sweep count — as stable as the reference.

use glam::Vec3A;

use crate::model::SimModel;
use crate::solvers::Sym3;

/// Largest component solved exactly (masses). Twelve unknowns: a dense solve is cheap.
pub(crate) const MAX_CLUSTER: usize = 4;

/// The connected components of the free masses (links to anchored masses don't connect).
#[derive(Clone, Debug, Default)]
pub(crate) struct Clusters {
    /// `members[start[c]..start[c + 1]]` are cluster `c`'s free masses, ascending.
    pub start: Vec<u32>,
    pub members: Vec<u32>,
    /// Each free mass's position inside its cluster.
    pub slot: Vec<u8>,
    /// Each free mass's cluster.
    pub cluster: Vec<u32>,
}

impl Clusters {
    /// The components when all have at most [`MAX_CLUSTER`] masses and at least one has two or
    /// more (otherwise the Jacobi sweep already is exact, or the components are too big).
    pub fn find(model: &SimModel) -> Option<Clusters> {
        let nf = model.n_free;
        // Union–find over free–free links.
        let mut parent: Vec<u32> = (0..nf as u32).collect();
        fn root(p: &mut [u32], mut i: u32) -> u32 {
            while p[i as usize] != i {
                let g = p[p[i as usize] as usize];
                p[i as usize] = g;
                i = g;
            }
            i
        }
        for k in 0..nf {
            for a in model.adj_of(k) {
                let j = a.other as usize;
                if j < nf {
                    let (ra, rb) = (root(&mut parent, k as u32), root(&mut parent, j as u32));
                    if ra != rb {
                        parent[ra.max(rb) as usize] = ra.min(rb);
                    }
                }
            }
        }
        // Members per root in ascending order (roots are each component's smallest mass).
        let mut size = vec![0u32; nf];
        for k in 0..nf {
            let r = root(&mut parent, k as u32) as usize;
            size[r] += 1;
        }
        let largest = size.iter().copied().max().unwrap_or(0) as usize;
        if !(2..=MAX_CLUSTER).contains(&largest) {
            return None;
        }
        let mut index = vec![u32::MAX; nf];
        let mut start = vec![0u32];
        for r in 0..nf {
            if size[r] > 0 {
                index[r] = (start.len() - 1) as u32;
                let last = *start.last().expect("start is never empty");
                start.push(last + size[r]);
            }
        }
        let mut fill: Vec<u32> = start[..start.len() - 1].to_vec();
        let mut members = vec![0u32; nf];
        let mut slot = vec![0u8; nf];
        let mut cluster = vec![0u32; nf];
        for k in 0..nf {
            let c = index[root(&mut parent, k as u32) as usize] as usize;
            cluster[k] = c as u32;
            slot[k] = (fill[c] - start[c]) as u8;
            members[fill[c] as usize] = k as u32;
            fill[c] += 1;
        }
        Some(Clusters { start, members, slot, cluster })
    }

    /// The cluster of free mass `k`.
    pub fn index_of(&self, k: usize) -> usize {
        self.cluster[k] as usize
    }

    /// Number of clusters.
    pub fn len(&self) -> usize {
        self.start.len() - 1
    }
}

/// One implicit step's linearised backward-Euler system `A Δv = b` (eq. 3.26–3.33), seen cluster
/// by cluster: `A_kk = (m_k + h² k_r) I + Σ_links B`, `A_kj = −Σ_links(k,j) B` with `B` the link
/// blocks `h c I + h² Kp` in adjacency order (`blocks`, unweighted) and `k_r` the restoring
/// stiffness.
pub(crate) struct ClusterSystem<'a> {
    pub model: &'a SimModel,
    pub clusters: &'a Clusters,
    /// Step length, seconds.
    pub h: f32,
    /// Weight `w` of the restoring force (eq. 3.37), newtons.
    pub restoring_w: f32,
    /// Per adjacency entry: the link's block `B`.
    pub blocks: &'a [Sym3],
    /// Per free mass: the right-hand side.
    pub b: &'a [Vec3A],
}

impl ClusterSystem<'_> {
    /// Solves cluster `c`'s block of `A Δv = b` exactly: its masses' `Δv`, indexed by slot (the
    /// entries past the cluster's size are zero). Gaussian elimination with partial pivoting in
    /// f64; a singular block (cannot happen for positive masses) gives NaN, which the
    /// simulator's finiteness check reports.
    pub fn solve(&self, c: usize) -> [Vec3A; MAX_CLUSTER] {
        let ClusterSystem { model, clusters, h, restoring_w, blocks, b } = *self;
        const N: usize = 3 * MAX_CLUSTER;
        let members = &clusters.members[clusters.start[c] as usize..clusters.start[c + 1] as usize];
        let n = 3 * members.len();
        let mut a = [[0.0f64; N + 1]; N];
        let h2 = (h as f64) * (h as f64);
        for (s, &k) in members.iter().enumerate() {
            let k = k as usize;
            let d = model.mass[k] as f64 + h2 * model.restoring_stiffness(k, restoring_w) as f64;
            for q in 0..3 {
                a[3 * s + q][3 * s + q] += d;
                a[3 * s + q][N] = b[k][q] as f64;
            }
            let base = model.adj_start[k] as usize;
            for (e, adj) in model.adj_of(k).iter().enumerate() {
                let m = sym_rows(&blocks[base + e]);
                let j = adj.other as usize;
                for r in 0..3 {
                    for q in 0..3 {
                        a[3 * s + r][3 * s + q] += m[r][q];
                    }
                }
                if j < model.n_free {
                    let t = clusters.slot[j] as usize;
                    for r in 0..3 {
                        for q in 0..3 {
                            a[3 * s + r][3 * t + q] -= m[r][q];
                        }
                    }
                }
            }
        }
        // Forward elimination with partial pivoting; the right-hand side rides in column N.
        for col in 0..n {
            let mut p = col;
            for r in col + 1..n {
                if a[r][col].abs() > a[p][col].abs() {
                    p = r;
                }
            }
            a.swap(col, p);
            let piv = a[col][col];
            let inv = if piv != 0.0 { 1.0 / piv } else { f64::NAN };
            for r in col + 1..n {
                let f = a[r][col] * inv;
                if f != 0.0 {
                    let pivot_row = a[col];
                    for (q, value) in a[r].iter_mut().enumerate().take(n).skip(col) {
                        *value -= f * pivot_row[q];
                    }
                    a[r][N] -= f * pivot_row[N];
                }
            }
        }
        let mut x = [0.0f64; N];
        for r in (0..n).rev() {
            let mut s = a[r][N];
            for q in r + 1..n {
                s -= a[r][q] * x[q];
            }
            x[r] = s / a[r][r];
        }
        let mut out = [Vec3A::ZERO; MAX_CLUSTER];
        for s in 0..members.len() {
            out[s] = Vec3A::new(x[3 * s] as f32, x[3 * s + 1] as f32, x[3 * s + 2] as f32);
        }
        out
    }
}

/// A symmetric block as rows.
fn sym_rows(m: &Sym3) -> [[f64; 3]; 3] {
    let q = m.0.map(|c| c as f64);
    [[q[0], q[3], q[4]], [q[3], q[1], q[5]], [q[4], q[5], q[2]]]
}
