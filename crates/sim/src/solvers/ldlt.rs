//! A small sparse `LDLᵀ` factorisation for the local/global solver's constant matrix
//! (`local_global.rs`): a minimum-degree fill-reducing ordering, the elimination-tree symbolic
//! analysis and the up-looking numeric factorisation of T. A. Davis's LDL ("Algorithm 849: a
//! concise sparse Cholesky factorization package", ACM TOMS 31(4), 2005), in f64.
//!
//! The pattern is analysed once ([`Ldlt::analyse`]); the numeric factor is recomputed whenever the
//! values change ([`Ldlt::factor`], e.g. a new step size) without allocating. Everything runs on
//! one thread in a fixed order, so the factor is bit-identical on every run.

#![allow(clippy::needless_range_loop)] // index loops mirror LDL's published algorithm

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::DVec3;

/// Marks "no parent" in the elimination tree.
const ROOT: u32 = u32::MAX;

/// A symmetric matrix's `LDLᵀ` factor under a fill-reducing permutation `P`:
/// `P A Pᵀ = L D Lᵀ`, `L` unit lower triangular, stored by columns.
#[derive(Debug, Default)]
pub(super) struct Ldlt {
    n: usize,
    /// The pattern of `A` (both triangles, diagonal included), rows in CSR.
    a_start: Vec<u32>,
    a_col: Vec<u32>,
    /// `perm[k]`: the original index of the `k`-th eliminated unknown; `inv[perm[k]] = k`.
    perm: Vec<u32>,
    inv: Vec<u32>,
    /// Elimination tree parent of every permuted column (ROOT for roots).
    parent: Vec<u32>,
    /// Columns of `L` (strictly below the diagonal): `l_row[l_start[j]..l_start[j + 1]]`.
    l_start: Vec<u32>,
    l_row: Vec<u32>,
    l_val: Vec<f64>,
    d: Vec<f64>,
    /// Numeric scratch: the dense row being eliminated, its pattern, visit flags and fill counts.
    y: Vec<f64>,
    pattern: Vec<u32>,
    flag: Vec<u32>,
    fill: Vec<u32>,
}

impl Ldlt {
    /// Orders and analyses the symmetric pattern given as CSR rows (`start`, `col`; both
    /// triangles; duplicates allowed). [`Ldlt::factor`] then takes values in the same layout.
    pub fn analyse(start: &[u32], col: &[u32]) -> Ldlt {
        let n = start.len() - 1;
        let perm = minimum_degree(n, start, col);
        let mut inv = vec![0u32; n];
        for (k, &p) in perm.iter().enumerate() {
            inv[p as usize] = k as u32;
        }
        // Elimination tree and column counts (LDL's `ldl_symbolic`).
        let mut parent = vec![ROOT; n];
        let mut flag = vec![0u32; n];
        let mut count = vec![0u32; n];
        for k in 0..n {
            flag[k] = k as u32;
            let row = perm[k] as usize;
            for &c in &col[start[row] as usize..start[row + 1] as usize] {
                let mut i = inv[c as usize] as usize;
                if i >= k {
                    continue;
                }
                while flag[i] != k as u32 {
                    if parent[i] == ROOT {
                        parent[i] = k as u32;
                    }
                    count[i] += 1;
                    flag[i] = k as u32;
                    i = parent[i] as usize;
                }
            }
        }
        let mut l_start = vec![0u32; n + 1];
        for k in 0..n {
            l_start[k + 1] = l_start[k] + count[k];
        }
        let nnz = l_start[n] as usize;
        Ldlt {
            n,
            a_start: start.to_vec(),
            a_col: col.to_vec(),
            perm,
            inv,
            parent,
            l_start,
            l_row: vec![0; nnz],
            l_val: vec![0.0; nnz],
            d: vec![0.0; n],
            y: vec![0.0; n],
            pattern: vec![0; n],
            flag,
            fill: count,
        }
    }

    /// Entries of `L` below the diagonal (the fill the ordering left).
    #[cfg(test)]
    pub fn factor_entries(&self) -> usize {
        self.l_row.len()
    }

    /// Factors the matrix with values `val` (aligned with the analysed pattern). Fails, naming
    /// the permuted column, when a pivot is not positive and finite (the matrix is not positive
    /// definite).
    pub fn factor(&mut self, val: &[f64]) -> Result<(), usize> {
        let n = self.n;
        // Flags left by the analysis (or a previous factor) must not stop this one's walks.
        self.flag.fill(ROOT);
        // LDL's `ldl_numeric`, up-looking: row k of L from the rows of its pattern.
        for k in 0..n {
            self.y[k] = 0.0;
            let mut top = n;
            self.flag[k] = k as u32;
            self.fill[k] = 0;
            let row = self.perm[k] as usize;
            for p in self.a_start[row] as usize..self.a_start[row + 1] as usize {
                let mut i = self.inv[self.a_col[p] as usize] as usize;
                if i > k {
                    continue;
                }
                self.y[i] += val[p];
                let mut len = 0;
                while self.flag[i] != k as u32 {
                    self.pattern[len] = i as u32;
                    len += 1;
                    self.flag[i] = k as u32;
                    i = self.parent[i] as usize;
                }
                while len > 0 {
                    top -= 1;
                    len -= 1;
                    self.pattern[top] = self.pattern[len];
                }
            }
            let mut dk = self.y[k];
            self.y[k] = 0.0;
            for t in top..n {
                let i = self.pattern[t] as usize;
                let yi = self.y[i];
                self.y[i] = 0.0;
                let (s, e) = (self.l_start[i] as usize, self.l_start[i] as usize + self.fill[i] as usize);
                for p in s..e {
                    self.y[self.l_row[p] as usize] -= self.l_val[p] * yi;
                }
                let l_ki = yi / self.d[i];
                dk -= l_ki * yi;
                self.l_row[e] = k as u32;
                self.l_val[e] = l_ki;
                self.fill[i] += 1;
            }
            if !(dk > 0.0 && dk.is_finite()) {
                return Err(k);
            }
            self.d[k] = dk;
        }
        Ok(())
    }

    /// Solves `A x = b` with the last factor: `b(i)` the right-hand side in the original order,
    /// `x` written in the original order, `work` (one per unknown) as scratch.
    pub fn solve(&self, b: impl Fn(usize) -> f64, x: &mut [f64], work: &mut [f64]) {
        for (k, w) in work[..self.n].iter_mut().enumerate() {
            *w = b(self.perm[k] as usize);
        }
        self.substitute(work);
        for k in 0..self.n {
            x[self.perm[k] as usize] = work[k];
        }
    }

    /// [`Ldlt::solve`] for three right-hand sides at once (`b[i]`'s x, y and z), reading the
    /// factor once: per coordinate the same operations in the same order as three `solve`s,
    /// except that a column is applied to all three when any of them is non-zero (subtracting
    /// `l · 0`, which can turn a `−0.0` into `+0.0` and changes nothing else).
    pub fn solve3(&self, b: &[DVec3], x: &mut [DVec3], work: &mut [DVec3]) {
        for (k, w) in work[..self.n].iter_mut().enumerate() {
            *w = b[self.perm[k] as usize];
        }
        self.substitute(work);
        for k in 0..self.n {
            x[self.perm[k] as usize] = work[k];
        }
    }

    /// `L D Lᵀ` solved in place on `work` (permuted order): forward substitution (a column is
    /// skipped when its value is zero), the diagonal, back substitution.
    fn substitute<T>(&self, work: &mut [T])
    where
        T: Copy + Default + PartialEq + std::ops::SubAssign + std::ops::DivAssign<f64>,
        f64: std::ops::Mul<T, Output = T>,
    {
        let n = self.n;
        for j in 0..n {
            let wj = work[j];
            if wj != T::default() {
                for p in self.l_start[j] as usize..self.l_start[j + 1] as usize {
                    work[self.l_row[p] as usize] -= self.l_val[p] * wj;
                }
            }
        }
        for j in 0..n {
            work[j] /= self.d[j];
        }
        for j in (0..n).rev() {
            let mut s = work[j];
            for p in self.l_start[j] as usize..self.l_start[j + 1] as usize {
                s -= self.l_val[p] * work[self.l_row[p] as usize];
            }
            work[j] = s;
        }
    }
}

/// A minimum-degree ordering of the symmetric pattern (CSR rows, self loops and duplicates
/// ignored): repeatedly eliminates the unknown with the fewest neighbours in the elimination
/// graph (ties: the lowest index). The elimination graph is kept implicitly as a *quotient graph*
/// (George & Liu 1989; the representation of AMD, Amestoy, Davis & Duff 1996): every eliminated
/// unknown becomes an *element*, the list of its still uneliminated neighbours, which stands for
/// the clique its elimination made; an unknown's neighbours are its remaining plain neighbours and
/// the members of its elements. Eliminating `p` merges `p`'s elements into a new one (they are
/// absorbed, as is any element the new one covers), drops from each member's plain neighbours
/// what the new element covers, and recomputes the members' degrees exactly. Storage stays
/// within the pattern plus the factor's pattern, and the work is far below the explicit graph's
/// clique insertions, while the order is the same as explicit minimum degree's (exact degrees,
/// same ties). No supervariables or
/// approximate degrees — fine for the tens of thousands of unknowns of fur, whose graphs are hair
/// trees (no fill) and surface meshes.
fn minimum_degree(n: usize, start: &[u32], col: &[u32]) -> Vec<u32> {
    // Plain neighbours (sorted, deduplicated, no self loops), elements per unknown, element members.
    let mut adj: Vec<Vec<u32>> = (0..n)
        .map(|i| {
            let mut a: Vec<u32> =
                col[start[i] as usize..start[i + 1] as usize].iter().copied().filter(|&j| j as usize != i).collect();
            a.sort_unstable();
            a.dedup();
            a
        })
        .collect();
    let mut elems: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut absorbed = vec![false; n];
    let mut degree: Vec<usize> = adj.iter().map(Vec::len).collect();
    let mut mark = vec![0usize; n];
    let mut stamp = 0usize;
    let (mut seen, mut seen_stamp) = (vec![0usize; n], 0usize);
    let (mut outside, mut outside_stamp) = (vec![0usize; n], vec![0usize; n]);
    // Candidates by (degree, index); an entry is stale once its unknown is eliminated or its
    // degree has changed (the current one was pushed then), and is skipped.
    let mut queue: BinaryHeap<Reverse<(usize, u32)>> = (0..n).map(|i| Reverse((degree[i], i as u32))).collect();
    let mut done = vec![false; n];
    let mut order = Vec::with_capacity(n);
    while let Some(Reverse((dp, p))) = queue.pop() {
        let pu = p as usize;
        if done[pu] || degree[pu] != dp {
            continue;
        }
        done[pu] = true;
        order.push(p);
        // The new element: p's plain neighbours and the members of p's elements (absorbed now).
        stamp += 1;
        mark[pu] = stamp;
        let mut lp = Vec::new();
        for &j in &std::mem::take(&mut adj[pu]) {
            if mark[j as usize] != stamp {
                mark[j as usize] = stamp;
                lp.push(j);
            }
        }
        for e in std::mem::take(&mut elems[pu]) {
            let e = e as usize;
            if absorbed[e] {
                continue;
            }
            absorbed[e] = true;
            for &j in &std::mem::take(&mut members[e]) {
                if mark[j as usize] != stamp {
                    mark[j as usize] = stamp;
                    lp.push(j);
                }
            }
        }
        // Members: p and what the new element covers leave the plain neighbours (marked now);
        // absorbed elements leave the element lists; the new element joins them. Meanwhile every
        // other element counts its members outside the new element (`outside`, AMD's `w`): one
        // with none is covered by the new one and is absorbed too (no degree changes).
        for &i in &lp {
            let i = i as usize;
            adj[i].retain(|&j| mark[j as usize] != stamp);
            elems[i].retain(|&e| !absorbed[e as usize]);
            for &e in &elems[i] {
                let e = e as usize;
                if outside_stamp[e] != stamp {
                    outside_stamp[e] = stamp;
                    outside[e] = members[e].len();
                }
                outside[e] -= 1;
            }
            elems[i].push(p);
        }
        for &i in &lp {
            for &e in &elems[i as usize] {
                let e = e as usize;
                if e != pu && outside[e] == 0 && !absorbed[e] {
                    absorbed[e] = true;
                    members[e] = Vec::new();
                }
            }
        }
        // Exact degrees of the members: the new element's other members, then what the plain
        // neighbours and the other elements add beyond it (its members keep their mark).
        for &i in &lp {
            let i = i as usize;
            seen_stamp += 1;
            let mut d = lp.len() - 1;
            for &j in &adj[i] {
                if seen[j as usize] != seen_stamp {
                    seen[j as usize] = seen_stamp;
                    d += 1;
                }
            }
            elems[i].retain(|&e| !absorbed[e as usize]);
            for &e in &elems[i] {
                if e == p {
                    continue;
                }
                for &j in &members[e as usize] {
                    let j = j as usize;
                    if mark[j] != stamp && seen[j] != seen_stamp {
                        seen[j] = seen_stamp;
                        d += 1;
                    }
                }
            }
            degree[i] = d;
            queue.push(Reverse((d, i as u32)));
        }
        members[pu] = lp;
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// The explicit-graph minimum degree that [`minimum_degree`] replaced, the reference for its
    /// order: repeatedly eliminates the unknown with the fewest neighbours (ties: the lowest
    /// index), joining its neighbours into a clique (slow: clique insertions into ordered sets).
    fn minimum_degree_explicit(n: usize, start: &[u32], col: &[u32]) -> Vec<u32> {
        let mut g: Vec<BTreeSet<u32>> = (0..n)
            .map(|i| {
                col[start[i] as usize..start[i + 1] as usize].iter().copied().filter(|&j| j as usize != i).collect()
            })
            .collect();
        let mut queue: BTreeSet<(usize, u32)> = (0..n).map(|i| (g[i].len(), i as u32)).collect();
        let mut order = Vec::with_capacity(n);
        while let Some((_, v)) = queue.pop_first() {
            order.push(v);
            let nb: Vec<u32> = std::mem::take(&mut g[v as usize]).into_iter().collect();
            for &a in &nb {
                queue.remove(&(g[a as usize].len(), a));
                g[a as usize].remove(&v);
            }
            for (i, &a) in nb.iter().enumerate() {
                for &b in &nb[i + 1..] {
                    g[a as usize].insert(b);
                    g[b as usize].insert(a);
                }
            }
            for &a in &nb {
                queue.insert((g[a as usize].len(), a));
            }
        }
        order
    }

    /// A 1-D Laplacian plus identity on a ring with a chord: the factor solves it to rounding.
    #[test]
    fn factor_solves_a_small_system() {
        let n = 7;
        let mut start = vec![0u32];
        let mut col = Vec::new();
        let mut val = Vec::new();
        let link = |i: usize, j: usize| {
            (j + n - i) % n == 1 || (i + n - j) % n == 1 || (i == 0 && j == 3) || (i == 3 && j == 0)
        };
        for i in 0..n {
            for j in 0..n {
                if i == j {
                    col.push(j as u32);
                    val.push(5.0 + i as f64);
                } else if link(i, j) {
                    col.push(j as u32);
                    val.push(-1.0);
                }
            }
            start.push(col.len() as u32);
        }
        let mut f = Ldlt::analyse(&start, &col);
        f.factor(&val).expect("positive definite");
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin() + 1.0).collect();
        let (mut x, mut w) = (vec![0.0; n], vec![0.0; n]);
        f.solve(|i| b[i], &mut x, &mut w);
        for i in 0..n {
            let mut ax = 0.0;
            for p in start[i] as usize..start[i + 1] as usize {
                ax += val[p] * x[col[p] as usize];
            }
            assert!((ax - b[i]).abs() < 1e-12, "row {i}: {ax} vs {}", b[i]);
        }
        // Three right-hand sides at once: the same solutions, bit for bit.
        let b3: Vec<DVec3> = (0..n).map(|i| DVec3::new(b[i], (i as f64).cos() * 3.0, -(i as f64) * 0.25)).collect();
        let (mut x3, mut w3) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
        f.solve3(&b3, &mut x3, &mut w3);
        for axis in 0..3 {
            f.solve(|i| b3[i][axis], &mut x, &mut w);
            for i in 0..n {
                assert_eq!(x3[i][axis].to_bits(), x[i].to_bits(), "axis {axis}, unknown {i}");
            }
        }
        // Not positive definite: refused.
        let bad: Vec<f64> = val.iter().map(|v| -v).collect();
        assert!(f.factor(&bad).is_err());
    }

    /// A path (a hair) eliminates leaf first without any fill.
    #[test]
    fn trees_eliminate_without_fill() {
        let n = 50;
        let mut start = vec![0u32];
        let mut col = Vec::new();
        for i in 0..n {
            if i > 0 {
                col.push(i as u32 - 1);
            }
            col.push(i as u32);
            if i + 1 < n {
                col.push(i as u32 + 1);
            }
            start.push(col.len() as u32);
        }
        let f = Ldlt::analyse(&start, &col);
        assert_eq!(f.factor_entries(), n - 1);
    }

    /// The quotient-graph ordering is explicit minimum degree's, unknown for unknown, on wrapped
    /// meshes with diagonals (the shape of `synth::synthetic_topology`'s tips) and on a sparser
    /// wrapped graph.
    #[test]
    fn quotient_graph_orders_like_explicit_minimum_degree() {
        for (n, offsets) in [(400usize, &[1usize, 20, 21][..]), (300, &[1, 17, 18, 16, 2][..]), (120, &[3, 40][..])] {
            let mut nb: Vec<Vec<u32>> = vec![Vec::new(); n];
            for &off in offsets {
                for i in 0..n {
                    let j = (i + off) % n;
                    nb[i].push(j as u32);
                    nb[j].push(i as u32);
                }
            }
            let mut start = vec![0u32];
            let mut col = Vec::new();
            for (i, row) in nb.iter().enumerate() {
                col.push(i as u32);
                col.extend_from_slice(row);
                start.push(col.len() as u32);
            }
            assert_eq!(minimum_degree(n, &start, &col), minimum_degree_explicit(n, &start, &col), "n {n}");
        }
    }
}
