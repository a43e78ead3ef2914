//! The peers' solvers beside ours: XPBD (Macklin, Müller & Chentanez 2016) and the fast
//! mass–spring method of Liu et al. 2013 (local/global steps). Each converges to what it claims
//! to converge to, checked against solutions computed here independently:
//!
//! - a hanging chain of stiff springs settles, under both, to the static equilibrium computed
//!   analytically (each spring stretched by the weight below it over `k`);
//! - converged local/global iterations equal one backward-Euler step of the *nonlinear* spring
//!   forces (and viscosity), solved here by Newton's method in f64, and the error shrinks as the
//!   iterations grow;
//! - both are bit-identical for 1 and 2 rayon threads.
//!
//! (The hard cases, skinning and randomised suites run them through `SolverKind::ALL`.)

use furbake_formats::sections::spring_topology::TopologyParams;
use furbake_sim::{ForceSet, SimError, Simulator, SolverKind, SolverSettings, SpringTopology, synth};

const G: f64 = 9.81;

/// A vertical chain: one anchored mass at the origin and `n` free masses of `m` below it, `l`
/// apart, joined by springs of stiffness `k` and damping `c`.
fn chain(n: usize, m: f32, l: f32, k: f32, c: f32) -> SpringTopology {
    let mut t = synth::stiff_net();
    t.mass_rest_positions.clear();
    t.mass_kg.clear();
    t.mass_anchored.clear();
    t.spring_ends.clear();
    t.spring_rest_lengths_m.clear();
    t.spring_stiffness_n_per_m.clear();
    t.spring_damping_n_s_per_m.clear();
    for i in 0..=n {
        t.mass_rest_positions.push([0.0, -(i as f32) * l, 0.0]);
        t.mass_kg.push(if i == 0 { 1.0 } else { m });
        t.mass_anchored.push(u8::from(i == 0));
        if i > 0 {
            t.spring_ends.push([i as u32 - 1, i as u32]);
            t.spring_rest_lengths_m.push(l);
            t.spring_stiffness_n_per_m.push(k);
            t.spring_damping_n_s_per_m.push(c);
        }
    }
    t.shell_vertex_masses = vec![[0, n as u32]];
    t
}

fn gravity_only() -> ForceSet {
    ForceSet { restoring_weight_n: 0.0, ..ForceSet::default() }
}

/// Largest distance of the chain's masses from the analytic static equilibrium, metres.
fn chain_error(settings: SolverSettings, steps: u32) -> f64 {
    let (n, m, l, k) = (5usize, 1e-3f32, 0.01f32, 1000.0f32);
    let t = chain(n, m, l, k, 0.02);
    let mut sim = Simulator::new(&t, settings).expect("valid chain");
    sim.set_forces(gravity_only()).expect("valid forces");
    for _ in 0..steps {
        sim.step(1.0 / 60.0).expect("stable");
    }
    let pos = sim.positions();
    let mut y = 0.0f64;
    let mut worst = 0.0f64;
    for (i, p) in pos.iter().enumerate().skip(1) {
        // Spring i carries the weight of masses i..=n.
        let below = (n + 1 - i) as f64 * m as f64 * G;
        y -= l as f64 + below / k as f64;
        let e = ((p[0] as f64).powi(2) + (p[1] as f64 - y).powi(2) + (p[2] as f64).powi(2)).sqrt();
        worst = worst.max(e);
    }
    worst
}

/// XPBD with enough iterations settles to the static equilibrium (the constraint solution with
/// compliance 1/k); with few it is visibly softer, the known iteration-count dependence of XPBD's
/// stiffness. Local/global (converged backward Euler) settles there too.
#[test]
fn hanging_chain_settles_to_the_analytic_equilibrium() {
    // The top spring stretches by 5 m g / k = 49 µm; the whole chain by 147 µm.
    let xpbd = |it| chain_error(SolverSettings { xpbd_iterations: it, ..SolverSettings::of(SolverKind::Xpbd) }, 600);
    let (few, many) = (xpbd(1), xpbd(100));
    let lg = chain_error(
        SolverSettings { local_global_iterations: 100, ..SolverSettings::of(SolverKind::LocalGlobal) },
        600,
    );
    eprintln!("chain error: xpbd×1 {few:.3e} m, xpbd×100 {many:.3e} m, local/global×100 {lg:.3e} m");
    assert!(many < 1e-6, "XPBD×100 is {many} m from the equilibrium");
    assert!(few > 10.0 * many, "one XPBD iteration should be visibly softer: {few} vs {many}");
    assert!(lg < 1e-6, "local/global×100 is {lg} m from the equilibrium");
}

/// A small dense Gaussian elimination with partial pivoting (the Newton steps' linear solves).
#[allow(clippy::needless_range_loop)] // textbook elimination, indices as in the formulas
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs())).expect("non-empty");
        a.swap(col, piv);
        b.swap(col, piv);
        for r in col + 1..n {
            let f = a[r][col] / a[col][col];
            if f != 0.0 {
                for c in col..n {
                    a[r][c] -= f * a[col][c];
                }
                b[r] -= f * b[col];
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x
}

/// One backward-Euler step of the nonlinear springs, viscosity and gravity, by Newton's method in
/// f64: `M (v' − v) = h F(x + h v', v')`, anchored masses fixed. Returns the new positions.
fn newton_step(t: &SpringTopology, x: &[[f32; 3]], v: &[[f32; 3]], h: f64) -> Vec<[f64; 3]> {
    let n = x.len();
    let free: Vec<usize> = (0..n).filter(|&i| t.mass_anchored[i] == 0).collect();
    let mut slot = vec![usize::MAX; n];
    for (s, &i) in free.iter().enumerate() {
        slot[i] = s;
    }
    let dim = 3 * free.len();
    let x0: Vec<[f64; 3]> = x.iter().map(|p| p.map(f64::from)).collect();
    let v0: Vec<[f64; 3]> = v.iter().map(|p| p.map(f64::from)).collect();
    let mut vn: Vec<[f64; 3]> = (0..n).map(|i| if slot[i] == usize::MAX { [0.0; 3] } else { v0[i] }).collect();
    for _ in 0..50 {
        let xn: Vec<[f64; 3]> = (0..n).map(|i| std::array::from_fn(|c| x0[i][c] + h * vn[i][c])).collect();
        // Residual r = M (v' − v) − h F and Jacobian J = M − h ∂F/∂v − h² ∂F/∂x.
        let mut r = vec![0.0; dim];
        let mut jac = vec![vec![0.0; dim]; dim];
        for (s, &i) in free.iter().enumerate() {
            let m = t.mass_kg[i] as f64;
            for c in 0..3 {
                r[3 * s + c] = m * (vn[i][c] - v0[i][c]) + h * m * G * (c == 1) as u8 as f64;
                jac[3 * s + c][3 * s + c] = m;
            }
        }
        for (e, &[a, b]) in t.spring_ends.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            let (k, c, rest) = (
                t.spring_stiffness_n_per_m[e] as f64,
                t.spring_damping_n_s_per_m[e] as f64,
                t.spring_rest_lengths_m[e] as f64,
            );
            let d: [f64; 3] = std::array::from_fn(|q| xn[b][q] - xn[a][q]);
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let u: [f64; 3] = std::array::from_fn(|q| d[q] / len);
            // Force on a: k (len − rest) u + c (v_b − v_a); on b the opposite.
            let fa: [f64; 3] = std::array::from_fn(|q| k * (len - rest) * u[q] + c * (vn[b][q] - vn[a][q]));
            // ∂f_a/∂x_b = K, ∂f_a/∂x_a = −K, K = k ((1 − rest/len) I + (rest/len) u uᵀ).
            let kk = |p: usize, q: usize| k * ((1.0 - rest / len) * (p == q) as u8 as f64 + rest / len * u[p] * u[q]);
            for (me, other, sign) in [(a, b, 1.0), (b, a, -1.0)] {
                if slot[me] == usize::MAX {
                    continue;
                }
                let sm = slot[me];
                for p in 0..3 {
                    r[3 * sm + p] -= h * sign * fa[p];
                    for q in 0..3 {
                        let dx = h * h * kk(p, q) + h * c * (p == q) as u8 as f64;
                        jac[3 * sm + p][3 * sm + q] += dx;
                        if slot[other] != usize::MAX {
                            jac[3 * sm + p][3 * slot[other] + q] -= dx;
                        }
                    }
                }
            }
        }
        let dv = solve_dense(jac, r.iter().map(|x| -x).collect());
        for (s, &i) in free.iter().enumerate() {
            for c in 0..3 {
                vn[i][c] += dv[3 * s + c];
            }
        }
        if dv.iter().map(|x| x.abs()).fold(0.0, f64::max) < 1e-14 {
            break;
        }
    }
    (0..n).map(|i| std::array::from_fn(|c| x0[i][c] + h * vn[i][c])).collect()
}

/// Converged local/global iterations are one backward-Euler step of the nonlinear springs
/// (Liu et al. 2013, §4), and more iterations get closer.
#[test]
fn local_global_converges_to_the_nonlinear_backward_euler_step() {
    let t = synth::stiff_net();
    let h = 1.0 / 30.0;
    // A swinging, stretched start: every free mass displaced and moving.
    let start = Simulator::new(&t, SolverSettings::of(SolverKind::Implicit)).expect("valid");
    let mut x = start.positions();
    let mut v = start.velocities();
    for (i, (p, q)) in x.iter_mut().zip(v.iter_mut()).enumerate() {
        if t.mass_anchored[i] == 0 {
            let s = i as f32;
            p[0] += 0.003 * (1.3 * s).sin();
            p[1] += 0.002 * (0.7 * s).cos();
            p[2] += 0.004 * (2.1 * s).sin();
            *q = [0.3 * (0.9 * s).cos(), -0.2 * (1.7 * s).sin(), 0.25 * (0.4 * s).sin()];
        }
    }
    let exact = newton_step(&t, &x, &v, h);
    let error = |iterations: u32| {
        let settings =
            SolverSettings { local_global_iterations: iterations, ..SolverSettings::of(SolverKind::LocalGlobal) };
        let mut sim = Simulator::new(&t, settings).expect("valid");
        sim.set_forces(gravity_only()).expect("valid");
        sim.set_state(&x, &v).expect("finite");
        sim.step(h).expect("one step");
        let got = sim.positions();
        got.iter()
            .zip(&exact)
            .map(|(p, q)| (0..3).map(|c| (p[c] as f64 - q[c]).powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max)
    };
    let its = [1, 2, 4, 8, 16, 64, 256, 2000];
    let errors: Vec<f64> = its.iter().map(|&it| error(it)).collect();
    eprintln!("local/global iterations {its:?}: max error vs Newton {errors:?} m");
    assert!(errors.windows(2).all(|w| w[1] <= w[0] * 1.01 + 1e-8), "error must not grow with iterations: {errors:?}");
    assert!(errors[0] > 1e-5, "one iteration is not yet converged: {errors:?}");
    // f32 state: positions of ~0.05 m hold ~4e-9 m.
    assert!(errors[7] < 1e-7, "converged iterations must match backward Euler: {errors:?}");
}

/// Both peers' solvers give bit-identical results on 1 and 2 threads (above the parallel cut-off;
/// with springs and with sticks).
#[test]
fn peers_are_deterministic_across_thread_counts() -> Result<(), SimError> {
    for sticks in [false, true] {
        let t = synth::synthetic_topology(12_000, 18_000, sticks, &TopologyParams::default()).expect("valid size");
        for kind in [SolverKind::Xpbd, SolverKind::LocalGlobal] {
            let run = || -> Result<Vec<[f32; 3]>, SimError> {
                let mut sim = Simulator::new(&t, SolverSettings::of(kind))?;
                sim.set_forces(ForceSet { wind: Some(furbake_sim::WindForce::default()), ..ForceSet::default() })?;
                for _ in 0..3 {
                    sim.step(1.0 / 60.0)?;
                }
                Ok(sim.positions())
            };
            let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
            let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("pool");
            let a = one.install(run)?;
            let b = two.install(run)?;
            assert!(
                a.iter().zip(&b).all(|(p, q)| p.map(f32::to_bits) == q.map(f32::to_bits)),
                "{} (sticks: {sticks})",
                kind.name()
            );
            let rest = &t.mass_rest_positions;
            assert!(a.iter().zip(rest).any(|(p, q)| p != q), "{}: nothing moved", kind.name());
        }
    }
    Ok(())
}

/// The new settings are validated like `implicit_iterations`.
#[test]
fn zero_iterations_are_refused() {
    let t = synth::stiff_net();
    for settings in [
        SolverSettings { xpbd_iterations: 0, ..SolverSettings::of(SolverKind::Xpbd) },
        SolverSettings { local_global_iterations: 0, ..SolverSettings::of(SolverKind::LocalGlobal) },
    ] {
        match Simulator::new(&t, settings) {
            Err(SimError::Parameter { name, .. }) => assert!(name.ends_with("_iterations"), "{name}"),
            Err(e) => panic!("unexpected {e}"),
            Ok(_) => panic!("zero iterations accepted"),
        }
    }
    assert_eq!(SolverKind::from_name("xpbd"), Some(SolverKind::Xpbd));
    assert_eq!(SolverKind::from_name("local_global"), Some(SolverKind::LocalGlobal));
}
