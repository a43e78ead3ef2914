//! Independent f64 integrators for the convergence and reference checks, written from the
//! equations alone (springs eq. 3.23–3.24, gravity, the travelling-gust wind of `forces.rs`):
//! classic RK4, linearised backward Euler (one Newton step per time step, Baraff & Witkin) and
//! nonlinear backward Euler (Newton to convergence), the latter two with the exact Jacobian and a
//! dense Gaussian elimination. They read the topology's arrays, never the solver's code.

use furbake_sim::{ForceSet, SpringTopology};

/// A mass–spring system with gravity and a position- and velocity-independent wind. The
/// restoring force is not modelled (the scenes used here have none or compare solvers only).
pub struct Net {
    pub n: usize,
    pub free: Vec<usize>,
    /// Per mass its index among the free masses, or `usize::MAX`.
    pub slot: Vec<usize>,
    pub mass: Vec<f64>,
    pub rest: Vec<[f64; 3]>,
    /// (a, b, rest length, stiffness, damping)
    pub springs: Vec<(usize, usize, f64, f64, f64)>,
    pub gravity: [f64; 3],
    /// (unit direction, force, amplitude, frequency, wavelength)
    pub wind: Option<([f64; 3], f64, f64, f64, f64)>,
    /// Clamp the springs' transverse stiffness `k (1 − L/l)` to `[0, k]` in the Jacobian (the
    /// implicit solver's system) instead of the exact Jacobian.
    pub clamp: bool,
    /// The restoring force of eq. 3.37 on two-mass topologies: per tip (tip, root, rest
    /// direction), and its weight.
    pub restoring: Vec<(usize, usize, [f64; 3])>,
    pub restoring_w: f64,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn get(x: &[f64], i: usize) -> [f64; 3] {
    [x[3 * i], x[3 * i + 1], x[3 * i + 2]]
}

impl Net {
    pub fn new(t: &SpringTopology, f: &ForceSet) -> Net {
        assert!(t.stick_ends.is_empty(), "springs only");
        let restoring_w = f.restoring_weight_n as f64;
        let mut restoring = Vec::new();
        if restoring_w != 0.0 {
            // Two-mass topologies only: every tip is restored towards its anchored root's rest
            // direction.
            for &[r, tp] in &t.shell_vertex_masses {
                let (r, tp) = (r as usize, tp as usize);
                assert!(t.mass_anchored[r] != 0 && t.mass_anchored[tp] == 0, "two-mass topology");
                if restoring.iter().any(|&(q, _, _)| q == tp) {
                    continue;
                }
                let d = sub(t.mass_rest_positions[tp].map(|c| c as f64), t.mass_rest_positions[r].map(|c| c as f64));
                let l = dot(d, d).sqrt();
                restoring.push((tp, r, d.map(|c| c / l)));
            }
        }
        let n = t.mass_kg.len();
        let free: Vec<usize> = (0..n).filter(|&i| t.mass_anchored[i] == 0).collect();
        let mut slot = vec![usize::MAX; n];
        for (s, &i) in free.iter().enumerate() {
            slot[i] = s;
        }
        let wind = f.wind.as_ref().map(|w| {
            let d = w.direction.map(|c| c as f64);
            let l = dot(d, d).sqrt();
            (
                d.map(|c| c / l),
                w.force_n as f64,
                w.gust_amplitude as f64,
                w.gust_frequency_hz as f64,
                w.gust_wavelength_m as f64,
            )
        });
        Net {
            n,
            free,
            slot,
            mass: t.mass_kg.iter().map(|&m| m as f64).collect(),
            rest: t.mass_rest_positions.iter().map(|p| p.map(|c| c as f64)).collect(),
            springs: (0..t.spring_ends.len())
                .map(|s| {
                    let [a, b] = t.spring_ends[s];
                    (
                        a as usize,
                        b as usize,
                        t.spring_rest_lengths_m[s] as f64,
                        t.spring_stiffness_n_per_m[s] as f64,
                        t.spring_damping_n_s_per_m[s] as f64,
                    )
                })
                .collect(),
            gravity: f.gravity_m_per_s2.map(|c| c as f64),
            wind,
            clamp: false,
            restoring,
            restoring_w,
        }
    }

    /// Rest positions, flat.
    pub fn rest_state(&self) -> Vec<f64> {
        self.rest.iter().flatten().copied().collect()
    }

    /// Force on every mass (zero on anchored ones), flat.
    pub fn force(&self, x: &[f64], v: &[f64], t: f64, out: &mut [f64]) {
        out.fill(0.0);
        for &i in &self.free {
            let mut f = self.gravity.map(|g| g * self.mass[i]);
            if let Some((d, force, amp, freq, wl)) = self.wind {
                let phase = std::f64::consts::TAU * (freq * t - dot(d, self.rest[i]) / wl);
                let s = force * (1.0 + amp * phase.sin());
                for c in 0..3 {
                    f[c] += d[c] * s;
                }
            }
            out[3 * i..3 * i + 3].copy_from_slice(&f);
        }
        for &(a, b, rest, k, c) in &self.springs {
            let d = sub(get(x, b), get(x, a));
            let dv = sub(get(v, b), get(v, a));
            let l = dot(d, d).sqrt();
            let s = k * (1.0 - rest / l);
            for q in 0..3 {
                let fa = d[q] * s + dv[q] * c;
                out[3 * a + q] += fa;
                out[3 * b + q] -= fa;
            }
        }
        for &(tp, r, n) in &self.restoring {
            // F = (n − s)(1 − n·s) w (eq. 3.37).
            let d = sub(get(x, tp), get(x, r));
            let l = dot(d, d).sqrt();
            let s = d.map(|c| c / l);
            let c = (1.0 - dot(n, s)) * self.restoring_w;
            for q in 0..3 {
                out[3 * tp + q] += (n[q] - s[q]) * c;
            }
        }
        for i in 0..self.n {
            if self.slot[i] == usize::MAX {
                out[3 * i..3 * i + 3].fill(0.0);
            }
        }
    }

    /// Dense `∂F/∂x` and `∂F/∂v` over the free degrees of freedom (row-major, `3 n_free` square).
    pub fn jacobians(&self, x: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let m = 3 * self.free.len();
        let (mut kx, mut kv) = (vec![0.0; m * m], vec![0.0; m * m]);
        for &(a, b, rest, k, c) in &self.springs {
            let d = sub(get(x, b), get(x, a));
            let l = dot(d, d).sqrt();
            let mut blk = [[0.0; 3]; 3];
            for (r, row) in blk.iter_mut().enumerate() {
                for (q, e) in row.iter_mut().enumerate() {
                    let beta = if self.clamp { (1.0 - rest / l).clamp(0.0, 1.0) } else { 1.0 - rest / l };
                    *e = k * (1.0 - beta) * d[r] * d[q] / (l * l) + if r == q { k * beta } else { 0.0 };
                }
            }
            // ∂F_a/∂x_b = K, ∂F_a/∂x_a = −K, and symmetrically for b.
            for (i, j, sign) in [(a, b, 1.0), (a, a, -1.0), (b, a, 1.0), (b, b, -1.0)] {
                let (si, sj) = (self.slot[i], self.slot[j]);
                if si == usize::MAX || sj == usize::MAX {
                    continue;
                }
                for r in 0..3 {
                    for q in 0..3 {
                        kx[(3 * si + r) * m + 3 * sj + q] += sign * blk[r][q];
                    }
                    kv[(3 * si + r) * m + 3 * sj + r] += sign * c;
                }
            }
        }
        for &(tp, _, n) in &self.restoring {
            // ∂F/∂x_tip = J = (w/l)(−c I − (n − s) nᵀ)(I − s sᵀ) (the root is anchored).
            let r = self.restoring.iter().find(|q| q.0 == tp).expect("listed").1;
            let d = sub(get(x, tp), get(x, r));
            let l = dot(d, d).sqrt();
            let s = d.map(|c| c / l);
            let c = 1.0 - dot(n, s);
            let u = sub(n, s);
            let left = |a: usize, b: usize| -(if a == b { c } else { 0.0 }) - u[a] * n[b];
            let proj = |a: usize, b: usize| (if a == b { 1.0 } else { 0.0 }) - s[a] * s[b];
            let st = self.slot[tp];
            for a in 0..3 {
                for b in 0..3 {
                    let j: f64 = (0..3).map(|q| left(a, q) * proj(q, b)).sum::<f64>() * self.restoring_w / l;
                    kx[(3 * st + a) * m + 3 * st + b] += j;
                }
            }
        }
        (kx, kv)
    }

    /// Classic RK4 for `duration` at step `dt`.
    pub fn rk4(&self, dt: f64, duration: f64) -> Vec<f64> {
        let steps = (duration / dt).round() as usize;
        let n3 = 3 * self.n;
        let (mut x, mut v) = (self.rest_state(), vec![0.0; n3]);
        let mut f = vec![0.0; n3];
        let (mut xs, mut vs) = (vec![0.0; n3], vec![0.0; n3]);
        let mut kx = [vec![0.0; n3], vec![0.0; n3], vec![0.0; n3], vec![0.0; n3]];
        let mut kv = kx.clone();
        let inv_m: Vec<f64> =
            (0..n3).map(|d| if self.slot[d / 3] == usize::MAX { 0.0 } else { 1.0 / self.mass[d / 3] }).collect();
        for s in 0..steps {
            let t = s as f64 * dt;
            for stage in 0..4 {
                let (c, tt) = match stage {
                    0 => (0.0, t),
                    1 | 2 => (0.5 * dt, t + 0.5 * dt),
                    _ => (dt, t + dt),
                };
                for d in 0..n3 {
                    let (px, pv) = if stage == 0 { (0.0, 0.0) } else { (kx[stage - 1][d], kv[stage - 1][d]) };
                    xs[d] = x[d] + c * px;
                    vs[d] = v[d] + c * pv;
                }
                self.force(&xs, &vs, tt, &mut f);
                for d in 0..n3 {
                    kx[stage][d] = vs[d] * if inv_m[d] == 0.0 { 0.0 } else { 1.0 };
                    kv[stage][d] = f[d] * inv_m[d];
                }
            }
            for d in 0..n3 {
                x[d] += dt / 6.0 * (kx[0][d] + 2.0 * kx[1][d] + 2.0 * kx[2][d] + kx[3][d]);
                v[d] += dt / 6.0 * (kv[0][d] + 2.0 * kv[1][d] + 2.0 * kv[2][d] + kv[3][d]);
            }
        }
        x
    }

    /// Backward Euler with forces at the step's start time: `newton = false` is one Newton
    /// step from `v` on `M (v' − v) = h F(x + h v', v')` with the force linearised at `x`
    /// (Baraff & Witkin's `(M − h ∂F/∂v − h² ∂F/∂x) Δv = h (F + h ∂F/∂x v)`); `newton = true`
    /// iterates Newton to convergence (nonlinear backward Euler).
    pub fn backward_euler(&self, dt: f64, duration: f64, newton: bool) -> Vec<f64> {
        let steps = (duration / dt).round() as usize;
        let n3 = 3 * self.n;
        let m = 3 * self.free.len();
        let (mut x, mut v) = (self.rest_state(), vec![0.0; n3]);
        let mut f = vec![0.0; n3];
        let (mut xn, mut vn) = (x.clone(), v.clone());
        for s in 0..steps {
            let t = s as f64 * dt;
            // Newton on g(v') = M (v' − v) − h F(x + h v', v') from v' = v.
            vn.copy_from_slice(&v);
            for it in 0..50 {
                for d in 0..n3 {
                    xn[d] = x[d] + dt * vn[d];
                }
                let (jx, jv) = self.jacobians(if it == 0 { &x } else { &xn });
                if it == 0 {
                    // Linearised at x: F(x + h v') ≈ F(x) + h ∂F/∂x v'.
                    self.force(&x, &v, t, &mut f);
                } else {
                    self.force(&xn, &vn, t, &mut f);
                }
                let mut a = vec![0.0; m * m];
                let mut rhs = vec![0.0; m];
                for (si, &i) in self.free.iter().enumerate() {
                    for r in 0..3 {
                        let row = 3 * si + r;
                        a[row * m + row] += self.mass[i];
                        for col in 0..m {
                            a[row * m + col] -= dt * jv[row * m + col] + dt * dt * jx[row * m + col];
                        }
                        let g = self.mass[i] * (vn[3 * i + r] - v[3 * i + r]) - dt * f[3 * i + r];
                        rhs[row] = -g;
                        if it == 0 {
                            // + h² ∂F/∂x v (the force was evaluated at x, not x + h v).
                            for (sj, &j) in self.free.iter().enumerate() {
                                for q in 0..3 {
                                    rhs[row] += dt * dt * jx[row * m + 3 * sj + q] * v[3 * j + q];
                                }
                            }
                        }
                    }
                }
                let dv = solve_dense(&mut a, &mut rhs, m);
                let mut norm = 0.0f64;
                for (si, &i) in self.free.iter().enumerate() {
                    for r in 0..3 {
                        vn[3 * i + r] += dv[3 * si + r];
                        norm = norm.max(dv[3 * si + r].abs());
                    }
                }
                if !newton || norm < 1e-13 {
                    break;
                }
            }
            v.copy_from_slice(&vn);
            for (x, v) in x.iter_mut().zip(&v) {
                *x += dt * v;
            }
        }
        x
    }

    /// RMS distance of the free masses between `a` (flat f64) and `b`.
    pub fn rms(&self, a: &[f64], b: &[f64]) -> f64 {
        let s: f64 =
            self.free.iter().map(|&i| (0..3).map(|q| (a[3 * i + q] - b[3 * i + q]).powi(2)).sum::<f64>()).sum();
        (s / self.free.len() as f64).sqrt()
    }
}

/// Gaussian elimination with partial pivoting (skipping zero multipliers: the band stays sparse).
pub fn solve_dense(a: &mut [f64], b: &mut [f64], m: usize) -> Vec<f64> {
    for c in 0..m {
        let p = (c..m).max_by(|&i, &j| a[i * m + c].abs().total_cmp(&a[j * m + c].abs())).expect("rows left");
        if p != c {
            for q in 0..m {
                a.swap(c * m + q, p * m + q);
            }
            b.swap(c, p);
        }
        let piv = a[c * m + c];
        assert!(piv != 0.0, "singular backward-Euler matrix");
        for r in c + 1..m {
            let f = a[r * m + c] / piv;
            if f == 0.0 {
                continue;
            }
            for q in c..m {
                a[r * m + q] -= f * a[c * m + q];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; m];
    for r in (0..m).rev() {
        let mut s = b[r];
        for q in r + 1..m {
            s -= a[r * m + q] * x[q];
        }
        x[r] = s / a[r * m + r];
    }
    x
}

/// Flattens the simulator's f32 positions to f64.
pub fn flat(p: &[[f32; 3]]) -> Vec<f64> {
    p.iter().flatten().map(|&c| c as f64).collect()
}
