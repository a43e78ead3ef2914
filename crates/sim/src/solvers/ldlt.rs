//! A small sparse `LDLᵀ` factorisation for the local/global solver's constant matrix
//! (`local_global.rs`): a minimum-degree fill-reducing ordering, the elimination-tree symbolic
//! analysis and the up-looking numeric factorisation of T. A. Davis's LDL ("Algorithm 849: a
//! concise sparse Cholesky factorization package", ACM TOMS 31(4), 2005), in f64.
//!
//! The pattern is analysed once ([`Ldlt::analyse`]); the numeric factor is recomputed whenever the
//! values change ([`Ldlt::factor`], e.g. a new step size) without allocating. Everything runs on
//! one thread in a fixed order, so the factor is bit-identical on every run.

#![allow(clippy::needless_range_loop)] // index loops mirror LDL's published algorithm

use std::collections::BTreeSet;

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
        let n = self.n;
        for k in 0..n {
            work[k] = b(self.perm[k] as usize);
        }
        for j in 0..n {
            let wj = work[j];
            if wj != 0.0 {
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
        for k in 0..n {
            x[self.perm[k] as usize] = work[k];
        }
    }
}

/// A minimum-degree ordering of the symmetric pattern (CSR rows, self loops and duplicates
/// ignored): repeatedly eliminates the unknown with the fewest neighbours in the elimination
/// graph (ties: the lowest index), joining its neighbours into a clique. Explicit graph, no
/// supervariables — fine for the few thousand to tens of thousands of unknowns of fur, whose
/// graphs are hair trees and surface meshes (trees eliminate without fill).
fn minimum_degree(n: usize, start: &[u32], col: &[u32]) -> Vec<u32> {
    let mut g: Vec<BTreeSet<u32>> = (0..n)
        .map(|i| col[start[i] as usize..start[i + 1] as usize].iter().copied().filter(|&j| j as usize != i).collect())
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
