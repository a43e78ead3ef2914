//! The four solvers' kernels (fur thesis §3.3.2, §3.4.1): one step of size `h` from `(x, v)` to
//! `(x_out, v_out)` for the free masses; anchored masses never move.
//!
//! - **Explicit** (eq. 3.20–3.25): forces at `t` (Hooke eq. 3.23, viscosity eq. 3.24, external),
//!   `v(t+h) = v + h M⁻¹F`, `p(t+h) = p + h v(t+h)`. Stable only below the step of
//!   [`stable_step`]; the simulator substeps.
//! - **Implicit** (eq. 3.26–3.34): the linearised backward-Euler system
//!   `(M − h ∂F/∂v − h² ∂F/∂x) Δv = h (F + h ∂F/∂x v)` solved by `iterations` Jacobi sweeps from
//!   `Δv = 0`; one sweep is the thesis's first iterate of eq. 3.34. Two deliberate changes, both
//!   needed for stability at large steps: the full 3×3 spring Jacobian of eq. 3.29 is used with the
//!   transverse term clamped at zero under compression, and the mass's own Jacobian blocks are
//!   moved to the left-hand side (eq. 3.34 as printed keeps only `M` there and diverges once
//!   `h²k/m > 1`) — a link between two free masses counts twice on the diagonal, which makes the
//!   diagonal dominate the system matrix so every sweep count is stable.
//! - **Stick** (§3.4.1, "orientation only"): every link from an anchored root is a rigid stick;
//!   external and remaining spring forces move the mass explicitly, the parent link's damping is
//!   implicit, then the mass is put back at the stick's length from its parent (level by level
//!   from the skin) and its velocity along the stick is removed.
//! - **Reference** (Baraff & Witkin 1998): the same linearised backward-Euler system without the
//!   diagonal trick, in f64, solved by block-Jacobi-preconditioned conjugate gradient to a tight
//!   relative residual. Used to measure everyone else's error.
//!
//! Sticks in the mass–spring solvers are projected after the step the same way.
//!
//! Layout for speed: the explicit, stick and one-sweep implicit kernels first evaluate every force
//! link once ([`link_forces`], `link_jacobians`: four links per SSE register on x86-64, lane
//! arrays elsewhere; the link's end `b` gets the exact negation), then each free mass gathers its
//! links' results — the links it is end `a` of are a contiguous range, those it is end `b` of a
//! short index list — and advances. No atomics, no scatter: every mass sums its own links in a
//! fixed order and every sum (CG dot products) uses fixed-size chunks combined in order, so the
//! result is bit-identical for any thread count. The reference solver assembles in parallel per
//! mass and fuses the CG vector updates with their dot products.

use glam::{DMat3, DVec3, Vec3A};
use rayon::prelude::*;

use crate::forces::{ForceEval, restoring_force};
use crate::model::{NONE, SimModel};

/// Masses per parallel work item; also the fixed chunk of deterministic sums.
pub(crate) const CHUNK: usize = 1024;
/// Below this many free masses the kernels run on the calling thread.
const PARALLEL_MIN: usize = 4096;

/// Runs `f(k)` for every free mass `k`, writing the returned `(x, v)` to `x_out[k]`, `v_out[k]`.
fn for_free<F>(n_free: usize, x_out: &mut [Vec3A], v_out: &mut [Vec3A], f: F)
where
    F: Fn(usize) -> (Vec3A, Vec3A) + Sync,
{
    let (xs, vs) = (&mut x_out[..n_free], &mut v_out[..n_free]);
    if n_free < PARALLEL_MIN {
        for (k, (xo, vo)) in xs.iter_mut().zip(vs.iter_mut()).enumerate() {
            (*xo, *vo) = f(k);
        }
        return;
    }
    xs.par_chunks_mut(CHUNK).zip(vs.par_chunks_mut(CHUNK)).enumerate().for_each(|(c, (xc, vc))| {
        for (o, (xo, vo)) in xc.iter_mut().zip(vc.iter_mut()).enumerate() {
            (*xo, *vo) = f(c * CHUNK + o);
        }
    });
}

/// Deterministic parallel sum of `f(k)` over `0..n` (fixed chunks, summed in order).
pub(crate) fn sum_over<F: Fn(usize) -> f64 + Sync>(n: usize, f: F) -> f64 {
    let chunks = n.div_ceil(CHUNK);
    let partial: Vec<f64> = if n < PARALLEL_MIN {
        (0..chunks).map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).map(&f).sum()).collect()
    } else {
        (0..chunks).into_par_iter().map(|c| (c * CHUNK..((c + 1) * CHUNK).min(n)).map(&f).sum()).collect()
    };
    partial.iter().sum()
}

#[inline(always)]
fn external(model: &SimModel, fe: &ForceEval, k: usize, xi: Vec3A, vi: Vec3A) -> Vec3A {
    if fe.uniform_only() { fe.accel * model.mass[k] } else { fe.external(model.mass[k], xi, vi, model.rest[k]) }
}

#[inline(always)]
fn restoring(model: &SimModel, fe: &ForceEval, x: &[Vec3A], k: usize, xi: Vec3A) -> Vec3A {
    let r = model.rest_parent[k];
    if r == NONE || fe.restoring_w == 0.0 {
        Vec3A::ZERO
    } else {
        restoring_force(x[r as usize], xi, model.rest_n[k], fe.restoring_w)
    }
}

/// Links per lane block of the per-link kernels (the math runs on whole blocks, so it
/// vectorises; a short last block is padded with zero-length links whose results are dropped).
const LANES: usize = 8;
/// Links per parallel work item of the per-link kernels.
const LINK_CHUNK: usize = 4096;
/// Below this many links the per-link kernels run on the calling thread.
const LINK_PARALLEL_MIN: usize = 8192;

/// Runs `f(first_link, out_chunk)` over `out` in fixed chunks (every link's result depends on
/// that link alone, so chunking never changes a result).
#[inline]
fn for_link_chunks<T: Send, F: Fn(usize, &mut [T]) + Sync>(out: &mut [T], f: F) {
    if out.len() < LINK_PARALLEL_MIN {
        f(0, out);
    } else {
        out.par_chunks_mut(LINK_CHUNK).enumerate().for_each(|(c, o)| f(c * LINK_CHUNK, o));
    }
}

/// One lane block of links: the position and velocity differences `x_b − x_a`, `v_b − v_a` and
/// the link constants, one lane per link.
struct LinkLanes {
    d: [[f32; LANES]; 3],
    dv: [[f32; LANES]; 3],
    rest: [f32; LANES],
    k: [f32; LANES],
    c: [f32; LANES],
    w: [f32; LANES],
}

impl LinkLanes {
    #[inline(always)]
    fn load(model: &SimModel, x: &[Vec3A], v: &[Vec3A], first: usize, count: usize) -> LinkLanes {
        let mut o = LinkLanes {
            d: [[0.0; LANES]; 3],
            dv: [[0.0; LANES]; 3],
            rest: [0.0; LANES],
            k: [0.0; LANES],
            c: [0.0; LANES],
            w: [0.0; LANES],
        };
        let r = first..first + count;
        let (sa, sb) = (&model.sp_a[r.clone()], &model.sp_b[r.clone()]);
        let (sr, sk, sc) = (&model.sp_rest[r.clone()], &model.sp_k[r.clone()], &model.sp_c[r]);
        for l in 0..count {
            let (a, b) = (sa[l] as usize, sb[l] as usize);
            let d = x[b] - x[a];
            let dv = v[b] - v[a];
            o.d[0][l] = d.x;
            o.d[1][l] = d.y;
            o.d[2][l] = d.z;
            o.dv[0][l] = dv.x;
            o.dv[1][l] = dv.y;
            o.dv[2][l] = dv.z;
            o.rest[l] = sr[l];
            o.k[l] = sk[l];
            o.c[l] = sc[l];
            o.w[l] = model.sp_w[first + l];
        }
        o
    }
}

/// Hooke + viscosity force (eq. 3.23–3.24) of every force link on its end `a`, computed once per
/// link (end `b` feels the negation), into `out` (resized to the link count).
pub(crate) fn link_forces(model: &SimModel, x: &[Vec3A], v: &[Vec3A], out: &mut Vec<Vec3A>) {
    out.resize(model.sp_a.len(), Vec3A::ZERO);
    for_link_chunks(out, |first, o| {
        #[cfg(target_arch = "x86_64")]
        {
            let n4 = o.len() / 4 * 4;
            let (head, tail) = o.split_at_mut(n4);
            link_forces_sse(model, x, v, first, head);
            link_forces_lanes(model, x, v, first + n4, tail);
        }
        #[cfg(not(target_arch = "x86_64"))]
        link_forces_lanes(model, x, v, first, o);
    });
}

/// [`link_forces`] on lane arrays (any architecture; the short tail on x86-64).
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn link_forces_lanes(model: &SimModel, x: &[Vec3A], v: &[Vec3A], first: usize, o: &mut [Vec3A]) {
    for (bi, ob) in o.chunks_mut(LANES).enumerate() {
        let n = ob.len();
        let ln = LinkLanes::load(model, x, v, first + bi * LANES, n);
        let mut f = [[0.0f32; LANES]; 3];
        for l in 0..LANES {
            let (dx, dy, dz) = (ln.d[0][l], ln.d[1][l], ln.d[2][l]);
            let len = (dx * dx + dy * dy + dz * dz).sqrt();
            // |d · (1 − rest/l)| = |l − rest| stays bounded as l → 0, and d = 0 gives 0.
            let t = ln.k[l] * (1.0 - ln.rest[l] / len.max(1e-20));
            for a in 0..3 {
                f[a][l] = ln.d[a][l] * t + ln.dv[a][l] * ln.c[l];
            }
        }
        for (l, out) in ob.iter_mut().enumerate() {
            *out = Vec3A::new(f[0][l], f[1][l], f[2][l]);
        }
    }
}

/// Transposes four SSE rows into four columns.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(unused_unsafe)]
fn sse_transpose(
    a: std::arch::x86_64::__m128,
    b: std::arch::x86_64::__m128,
    c: std::arch::x86_64::__m128,
    d: std::arch::x86_64::__m128,
) -> [std::arch::x86_64::__m128; 4] {
    use std::arch::x86_64::*;
    unsafe {
        let t0 = _mm_unpacklo_ps(a, b);
        let t1 = _mm_unpacklo_ps(c, d);
        let t2 = _mm_unpackhi_ps(a, b);
        let t3 = _mm_unpackhi_ps(c, d);
        [_mm_movelh_ps(t0, t1), _mm_movehl_ps(t1, t0), _mm_movelh_ps(t2, t3), _mm_movehl_ps(t3, t2)]
    }
}

/// [`link_forces`] four links at a time in SSE registers (the same operations in the same
/// order as [`link_forces_lanes`], so the results are bit-identical). `o.len()` is a multiple of 4.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(unused_unsafe)]
fn link_forces_sse(model: &SimModel, x: &[Vec3A], v: &[Vec3A], first: usize, o: &mut [Vec3A]) {
    use std::arch::x86_64::*;
    let n = o.len();
    let r = first..first + n;
    let (sa, sb) = (&model.sp_a[r.clone()], &model.sp_b[r.clone()]);
    let (sr, sk, sc) = (&model.sp_rest[r.clone()], &model.sp_k[r.clone()], &model.sp_c[r]);
    for (g, og) in o.chunks_exact_mut(4).enumerate() {
        let i = 4 * g;
        let d: [__m128; 4] = std::array::from_fn(|l| (x[sb[i + l] as usize] - x[sa[i + l] as usize]).into());
        let dv: [__m128; 4] = std::array::from_fn(|l| (v[sb[i + l] as usize] - v[sa[i + l] as usize]).into());
        unsafe {
            let [dx, dy, dz, _] = sse_transpose(d[0], d[1], d[2], d[3]);
            let [vx, vy, vz, _] = sse_transpose(dv[0], dv[1], dv[2], dv[3]);
            let rest = _mm_loadu_ps(sr[i..i + 4].as_ptr());
            let k = _mm_loadu_ps(sk[i..i + 4].as_ptr());
            let c = _mm_loadu_ps(sc[i..i + 4].as_ptr());
            let len2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
            let len = _mm_sqrt_ps(len2);
            // f32::max(len, 1e-20) (1e-20 when len is NaN, as `maxps` with the constant second).
            let lm = _mm_max_ps(len, _mm_set1_ps(1e-20));
            let t = _mm_mul_ps(k, _mm_sub_ps(_mm_set1_ps(1.0), _mm_div_ps(rest, lm)));
            let fx = _mm_add_ps(_mm_mul_ps(dx, t), _mm_mul_ps(vx, c));
            let fy = _mm_add_ps(_mm_mul_ps(dy, t), _mm_mul_ps(vy, c));
            let fz = _mm_add_ps(_mm_mul_ps(dz, t), _mm_mul_ps(vz, c));
            let f = sse_transpose(fx, fy, fz, _mm_setzero_ps());
            for l in 0..4 {
                og[l] = Vec3A::from(f[l]);
            }
        }
    }
}

/// The link forces on free mass `k` added to `f`: `f + (Σ over links it is end a of −
/// Σ over links it is end b of)`, each sum in link order (two independent chains).
#[inline(always)]
fn gather_links(model: &SimModel, fs: &[Vec3A], k: usize, f: Vec3A) -> Vec3A {
    let mut fa = Vec3A::ZERO;
    for q in &fs[model.sa_start[k] as usize..model.sa_start[k + 1] as usize] {
        fa += *q;
    }
    let mut fb = Vec3A::ZERO;
    for &sp in &model.gb_link[model.gb_start[k] as usize..model.gb_start[k + 1] as usize] {
        fb += fs[sp as usize];
    }
    f + (fa - fb)
}

/// Total force on free mass `k` at state `(x, v)`: external, restoring, links (from the per-link
/// forces `fs` of [`link_forces`]).
#[inline(always)]
fn total_force(model: &SimModel, fe: &ForceEval, x: &[Vec3A], v: &[Vec3A], fs: &[Vec3A], k: usize) -> Vec3A {
    let xi = x[k];
    let f = external(model, fe, k, xi, v[k]) + restoring(model, fe, x, k, xi);
    gather_links(model, fs, k, f)
}

/// The largest stable explicit step (with safety factor `safety`) for the links in the model's
/// adjacency: a Gershgorin bound `λ` on the eigenvalues of `M^{-1/2} K M^{-1/2}` and `γ` on the
/// damping, and the symplectic-Euler stability condition `λh² + 2γh < 4`. Infinity when nothing
/// constrains the step.
pub(crate) fn stable_step(model: &SimModel, restoring_w: f32, include_parent_damping: bool, safety: f32) -> f64 {
    let mut best = f64::INFINITY;
    for k in 0..model.n_free {
        let mi = model.mass[k] as f64;
        let (mut lam, mut gam) = (model.restoring_stiffness(k, restoring_w) as f64 / mi, 0.0f64);
        for a in model.adj_of(k) {
            let j = a.other as usize;
            let coupling = if j < model.n_free { 1.0 / (mi * model.mass[j] as f64).sqrt() } else { 0.0 };
            lam += a.k as f64 * (1.0 / mi + coupling);
            gam += a.c as f64 * (1.0 / mi + coupling);
        }
        if include_parent_damping && model.parent[k] != NONE {
            gam += model.parent_c[k] as f64 / mi;
        }
        let h = if lam > 0.0 {
            (-gam + (gam * gam + 4.0 * lam).sqrt()) / lam
        } else if gam > 0.0 {
            2.0 / gam
        } else {
            f64::INFINITY
        };
        best = best.min(h);
    }
    best * safety as f64
}

/// One explicit Euler step (eq. 3.20–3.25).
#[allow(clippy::too_many_arguments)]
pub(crate) fn explicit_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    x: &[Vec3A],
    v: &[Vec3A],
    scratch: &mut ImplicitScratch,
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
) {
    link_forces(model, x, v, &mut scratch.link_f);
    let fs = &scratch.link_f;
    for_free(model.n_free, x_out, v_out, |k| {
        let f = total_force(model, fe, x, v, fs, k);
        let vn = v[k] + f * (h * model.inv_mass[k]);
        (x[k] + vn * h, vn)
    });
    project_sticks(model, x_out, v_out);
}

/// One stick-solver step: explicit forces, implicit parent damping, then projection.
#[allow(clippy::too_many_arguments)]
pub(crate) fn stick_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    x: &[Vec3A],
    v: &[Vec3A],
    scratch: &mut ImplicitScratch,
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
) {
    link_forces(model, x, v, &mut scratch.link_f);
    let fs = &scratch.link_f;
    for_free(model.n_free, x_out, v_out, |k| {
        let f = total_force(model, fe, x, v, fs, k);
        let a = h * model.inv_mass[k];
        let p = model.parent[k];
        let vn = if p == NONE {
            v[k] + f * a
        } else {
            let ac = a * model.parent_c[k];
            (v[k] + f * a + v[p as usize] * ac) / (1.0 + ac)
        };
        (x[k] + vn * h, vn)
    });
    project_sticks(model, x_out, v_out);
}

/// Puts every mass with a rigid parent link back at the link's length from its (already placed)
/// parent, level by level from the skin, and removes the velocity component along the link
/// (relative to the parent). The position correction adds no velocity: a teleported stick snaps
/// back without being flung, and velocities are not computed as `(x_new − x_old)/h`, which in
/// f32 amplifies rounding by `1/h` and stops small steps from converging.
pub(crate) fn project_sticks(model: &SimModel, x_out: &mut [Vec3A], v_out: &mut [Vec3A]) {
    if !model.has_sticks {
        return;
    }
    let nf = model.n_free;
    for &(s, e) in &model.levels {
        let (placed_x, rest_x) = x_out.split_at_mut(s);
        let (placed_v, rest_v) = v_out.split_at_mut(s);
        let level_x = &mut rest_x[..e - s];
        let level_v = &mut rest_v[..e - s];
        let anchored = &model.rest[nf..];
        let place = |k: usize, xo: &mut Vec3A, vo: &mut Vec3A| {
            let p = model.parent[k];
            if p == NONE {
                return;
            }
            let p = p as usize;
            // Parents lie on a lower level (already placed) or are anchored (at rest, still).
            let (xp, vp) = if p < nf { (placed_x[p], placed_v[p]) } else { (anchored[p - nf], Vec3A::ZERO) };
            let dir =
                (*xo - xp).try_normalize().unwrap_or_else(|| (model.rest[k] - model.rest[p]).normalize_or(Vec3A::Y));
            *xo = xp + dir * model.parent_len[k];
            let rel = *vo - vp;
            *vo -= dir * rel.dot(dir);
        };
        if e - s < PARALLEL_MIN {
            for (o, (xo, vo)) in level_x.iter_mut().zip(level_v.iter_mut()).enumerate() {
                place(s + o, xo, vo);
            }
        } else {
            level_x.par_chunks_mut(CHUNK).zip(level_v.par_chunks_mut(CHUNK)).enumerate().for_each(|(c, (xc, vc))| {
                for (o, (xo, vo)) in xc.iter_mut().zip(vc.iter_mut()).enumerate() {
                    place(s + c * CHUNK + o, xo, vo);
                }
            });
        }
    }
}

/// Symmetric 3×3 matrix `[xx, yy, zz, xy, xz, yz]`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Sym3(pub [f32; 6]);

impl Sym3 {
    #[inline(always)]
    fn scaled_identity(s: f32) -> Sym3 {
        Sym3([s, s, s, 0.0, 0.0, 0.0])
    }
    #[inline(always)]
    fn add_scaled(&mut self, o: &Sym3, s: f32) {
        for i in 0..6 {
            self.0[i] += o.0[i] * s;
        }
    }
    #[inline(always)]
    fn mul(&self, v: Vec3A) -> Vec3A {
        let m = &self.0;
        Vec3A::new(
            m[0] * v.x + m[3] * v.y + m[4] * v.z,
            m[3] * v.x + m[1] * v.y + m[5] * v.z,
            m[4] * v.x + m[5] * v.y + m[2] * v.z,
        )
    }
    /// Solves `self · x = b` by the adjugate (the matrix is symmetric positive definite by
    /// construction); NaN when it is singular, which the simulator's finiteness check reports.
    #[inline(always)]
    fn solve(&self, b: Vec3A) -> Vec3A {
        let [a, e, i, bb, c, f] = self.0;
        let (c00, c01, c02) = (e * i - f * f, c * f - bb * i, bb * f - c * e);
        let (c11, c12, c22) = (a * i - c * c, bb * c - a * f, a * e - bb * bb);
        let det = a * c00 + bb * c01 + c * c02;
        if !(det.is_finite() && det > 0.0) {
            return Vec3A::splat(f32::NAN);
        }
        let r = 1.0 / det;
        Vec3A::new(
            (c00 * b.x + c01 * b.y + c02 * b.z) * r,
            (c01 * b.x + c11 * b.y + c12 * b.z) * r,
            (c02 * b.x + c12 * b.y + c22 * b.z) * r,
        )
    }
}

/// Hooke + viscosity force on mass i from a link (as [`link_force`]) and the link's stiffness
/// block `Kp = k (β I + (1 − β) d̂d̂ᵀ)` (eq. 3.29 with the transverse term `β = 1 − rest/l`
/// clamped to [0, 1], so the block is positive semi-definite); `∂F_i/∂x_j = Kp`,
/// `∂F_i/∂x_i = −Kp`. One square root and one division.
#[inline(always)]
fn force_and_block(d: Vec3A, dv: Vec3A, rest: f32, k: f32, c: f32) -> (Vec3A, Sym3) {
    let l = d.length();
    let inv_l = 1.0 / l.max(1e-20);
    let force = d * (k * (1.0 - rest * inv_l)) + dv * c;
    if k == 0.0 {
        return (force, Sym3::default());
    }
    if l <= 1e-12 {
        return (force, Sym3::scaled_identity(if rest == 0.0 { k } else { 0.0 }));
    }
    let beta = (1.0 - rest * inv_l).clamp(0.0, 1.0);
    let u = d * inv_l;
    let g = k * (1.0 - beta);
    let kb = k * beta;
    (
        force,
        Sym3([kb + g * u.x * u.x, kb + g * u.y * u.y, kb + g * u.z * u.z, g * u.x * u.y, g * u.x * u.z, g * u.y * u.z]),
    )
}

/// One force link's share of the implicit system, computed once per link (as
/// [`force_and_block`], in lanes): `g = f + h Kp (v_b − v_a)` with `f` its force on end `a`
/// (the link's part of the right-hand side before the final factor `h`), and `h c I + h² Kp`
/// scaled by the link's diagonal weight. End `b` sees `−g` and the same block.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(16))]
pub(crate) struct LinkJac {
    g: Vec3A,
    /// The six block entries `[xx, yy, zz, xy, xz, yz]`, two of padding.
    hb: [f32; 8],
}

/// [`LinkJac`] of every force link for step `h`, into `out` (resized to the link count).
fn link_jacobians(model: &SimModel, h: f32, x: &[Vec3A], v: &[Vec3A], out: &mut Vec<LinkJac>) {
    out.resize(model.sp_a.len(), LinkJac::default());
    for_link_chunks(out, |first, o| {
        #[cfg(target_arch = "x86_64")]
        {
            let n4 = o.len() / 4 * 4;
            let (head, tail) = o.split_at_mut(n4);
            link_jacobians_sse(model, h, x, v, first, head);
            link_jacobians_lanes(model, h, x, v, first + n4, tail);
        }
        #[cfg(not(target_arch = "x86_64"))]
        link_jacobians_lanes(model, h, x, v, first, o);
    });
}

/// [`link_jacobians`] on lane arrays (any architecture; the short tail on x86-64).
#[inline(always)]
#[allow(clippy::needless_range_loop, clippy::manual_clamp)]
fn link_jacobians_lanes(model: &SimModel, h: f32, x: &[Vec3A], v: &[Vec3A], first: usize, o: &mut [LinkJac]) {
    let h2 = h * h;
    for (bi, ob) in o.chunks_mut(LANES).enumerate() {
        let n = ob.len();
        let ln = LinkLanes::load(model, x, v, first + bi * LANES, n);
        let mut f = [[0.0f32; LANES]; 3];
        let mut kdv = [[0.0f32; LANES]; 3];
        let mut hb = [[0.0f32; LANES]; 6];
        for l in 0..LANES {
            let (dx, dy, dz) = (ln.d[0][l], ln.d[1][l], ln.d[2][l]);
            let (k, c, rest) = (ln.k[l], ln.c[l], ln.rest[l]);
            let len = (dx * dx + dy * dy + dz * dz).sqrt();
            let inv_l = 1.0 / len.max(1e-20);
            let t = 1.0 - rest * inv_l;
            let kt = k * t;
            for a in 0..3 {
                f[a][l] = ln.d[a][l] * kt + ln.dv[a][l] * c;
            }
            // max/min, not clamp: a NaN `t` (overflowed state) gives 0, as `maxps` does.
            let beta = t.max(0.0).min(1.0);
            let (ux, uy, uz) = (dx * inv_l, dy * inv_l, dz * inv_l);
            let g = k * (1.0 - beta);
            let kb = k * beta;
            let mut kp = [kb + g * ux * ux, kb + g * uy * uy, kb + g * uz * uz, g * ux * uy, g * ux * uz, g * uy * uz];
            if len <= 1e-12 {
                let iso = if rest == 0.0 { k } else { 0.0 };
                kp = [iso, iso, iso, 0.0, 0.0, 0.0];
            }
            if k == 0.0 {
                kp = [0.0; 6];
            }
            let (vx, vy, vz) = (ln.dv[0][l], ln.dv[1][l], ln.dv[2][l]);
            kdv[0][l] = kp[0] * vx + kp[3] * vy + kp[4] * vz;
            kdv[1][l] = kp[3] * vx + kp[1] * vy + kp[5] * vz;
            kdv[2][l] = kp[4] * vx + kp[5] * vy + kp[2] * vz;
            let hc = h * c;
            let w = ln.w[l];
            for q in 0..3 {
                hb[q][l] = (hc + kp[q] * h2) * w;
            }
            for q in 3..6 {
                hb[q][l] = kp[q] * h2 * w;
            }
        }
        for (l, out) in ob.iter_mut().enumerate() {
            *out = LinkJac {
                g: Vec3A::new(f[0][l], f[1][l], f[2][l]) + Vec3A::new(kdv[0][l], kdv[1][l], kdv[2][l]) * h,
                hb: [hb[0][l], hb[1][l], hb[2][l], hb[3][l], hb[4][l], hb[5][l], 0.0, 0.0],
            };
        }
    }
}

/// [`link_jacobians`] four links at a time in SSE registers (the operations of
/// [`link_jacobians_lanes`], branches as masks). `o.len()` is a multiple of 4.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[allow(unused_unsafe)]
fn link_jacobians_sse(model: &SimModel, h: f32, x: &[Vec3A], v: &[Vec3A], first: usize, o: &mut [LinkJac]) {
    use std::arch::x86_64::*;
    let n = o.len();
    let r = first..first + n;
    let (sa, sb) = (&model.sp_a[r.clone()], &model.sp_b[r.clone()]);
    let (sr, sk, sc, sw) = (&model.sp_rest[r.clone()], &model.sp_k[r.clone()], &model.sp_c[r.clone()], &model.sp_w[r]);
    for (g, og) in o.chunks_exact_mut(4).enumerate() {
        let i = 4 * g;
        let d: [__m128; 4] = std::array::from_fn(|l| (x[sb[i + l] as usize] - x[sa[i + l] as usize]).into());
        let dv: [__m128; 4] = std::array::from_fn(|l| (v[sb[i + l] as usize] - v[sa[i + l] as usize]).into());
        unsafe {
            let sel = |m: __m128, a: __m128, b: __m128| _mm_or_ps(_mm_and_ps(m, a), _mm_andnot_ps(m, b));
            let [dx, dy, dz, _] = sse_transpose(d[0], d[1], d[2], d[3]);
            let [vx, vy, vz, _] = sse_transpose(dv[0], dv[1], dv[2], dv[3]);
            let rest = _mm_loadu_ps(sr[i..i + 4].as_ptr());
            let k = _mm_loadu_ps(sk[i..i + 4].as_ptr());
            let c = _mm_loadu_ps(sc[i..i + 4].as_ptr());
            let w = _mm_loadu_ps(sw[i..i + 4].as_ptr());
            let zero = _mm_setzero_ps();
            let one = _mm_set1_ps(1.0);
            let len2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
            let len = _mm_sqrt_ps(len2);
            let inv_l = _mm_div_ps(one, _mm_max_ps(len, _mm_set1_ps(1e-20)));
            let t = _mm_sub_ps(one, _mm_mul_ps(rest, inv_l));
            let kt = _mm_mul_ps(k, t);
            let fx = _mm_add_ps(_mm_mul_ps(dx, kt), _mm_mul_ps(vx, c));
            let fy = _mm_add_ps(_mm_mul_ps(dy, kt), _mm_mul_ps(vy, c));
            let fz = _mm_add_ps(_mm_mul_ps(dz, kt), _mm_mul_ps(vz, c));
            let beta = _mm_min_ps(_mm_max_ps(t, zero), one);
            let (ux, uy, uz) = (_mm_mul_ps(dx, inv_l), _mm_mul_ps(dy, inv_l), _mm_mul_ps(dz, inv_l));
            let gg = _mm_mul_ps(k, _mm_sub_ps(one, beta));
            let kb = _mm_mul_ps(k, beta);
            let mut kp = [
                _mm_add_ps(kb, _mm_mul_ps(_mm_mul_ps(gg, ux), ux)),
                _mm_add_ps(kb, _mm_mul_ps(_mm_mul_ps(gg, uy), uy)),
                _mm_add_ps(kb, _mm_mul_ps(_mm_mul_ps(gg, uz), uz)),
                _mm_mul_ps(_mm_mul_ps(gg, ux), uy),
                _mm_mul_ps(_mm_mul_ps(gg, ux), uz),
                _mm_mul_ps(_mm_mul_ps(gg, uy), uz),
            ];
            // Zero length: an isotropic block (k for a zero-rest link, else 0); k = 0: no block.
            let small = _mm_cmple_ps(len, _mm_set1_ps(1e-12));
            let iso = _mm_and_ps(_mm_cmpeq_ps(rest, zero), k);
            let keep = _mm_cmpneq_ps(k, zero);
            for (q, kq) in kp.iter_mut().enumerate() {
                let s = sel(small, if q < 3 { iso } else { zero }, *kq);
                *kq = _mm_and_ps(keep, s);
            }
            let kdx = _mm_add_ps(_mm_add_ps(_mm_mul_ps(kp[0], vx), _mm_mul_ps(kp[3], vy)), _mm_mul_ps(kp[4], vz));
            let kdy = _mm_add_ps(_mm_add_ps(_mm_mul_ps(kp[3], vx), _mm_mul_ps(kp[1], vy)), _mm_mul_ps(kp[5], vz));
            let kdz = _mm_add_ps(_mm_add_ps(_mm_mul_ps(kp[4], vx), _mm_mul_ps(kp[5], vy)), _mm_mul_ps(kp[2], vz));
            let (hv, h2v) = (_mm_set1_ps(h), _mm_set1_ps(h * h));
            let hc = _mm_mul_ps(hv, c);
            let hb: [__m128; 6] = std::array::from_fn(|q| {
                let s = _mm_mul_ps(kp[q], h2v);
                _mm_mul_ps(if q < 3 { _mm_add_ps(hc, s) } else { s }, w)
            });
            let gx = _mm_add_ps(fx, _mm_mul_ps(kdx, hv));
            let gy = _mm_add_ps(fy, _mm_mul_ps(kdy, hv));
            let gz = _mm_add_ps(fz, _mm_mul_ps(kdz, hv));
            let gt = sse_transpose(gx, gy, gz, zero);
            let h03 = sse_transpose(hb[0], hb[1], hb[2], hb[3]);
            let h45 = sse_transpose(hb[4], hb[5], zero, zero);
            for l in 0..4 {
                let out = &mut og[l];
                out.g = Vec3A::from(gt[l]);
                _mm_storeu_ps(out.hb[0..4].as_mut_ptr(), h03[l]);
                _mm_storeu_ps(out.hb[4..8].as_mut_ptr(), h45[l]);
            }
        }
    }
}

/// Per-step scratch of the mass–spring solvers (kept between steps to avoid reallocating).
#[derive(Default)]
pub(crate) struct ImplicitScratch {
    link_f: Vec<Vec3A>,
    link_jac: Vec<LinkJac>,
    b: Vec<Vec3A>,
    diag: Vec<Sym3>,
    blocks: Vec<Sym3>,
    dv: Vec<Vec3A>,
    res: Vec<Vec3A>,
    dinv: Vec<DMat3>,
    rp: Vec<DVec3>,
    z: Vec<DVec3>,
}

fn sym_to_dmat(m: &Sym3) -> DMat3 {
    let q = m.0.map(|c| c as f64);
    DMat3::from_cols_array(&[q[0], q[3], q[4], q[3], q[1], q[5], q[4], q[5], q[2]])
}

/// One implicit Euler step (eq. 3.26–3.34) with `iterations` sweeps.
///
/// Each sweep solves `P z = b − A Δv` and adds `z` to `Δv`, where `P` keeps the exact couplings
/// along each hair (a free mass and its free parent, solved by elimination from the tips down
/// to the roots and back) and replaces every other link between free masses by twice its block
/// on the diagonal (`P ≥ A`, so the sweeps converge and the step stays stable). For the two-mass
/// topologies there is nothing to eliminate and one sweep is one 3×3 solve per mass.
#[allow(clippy::too_many_arguments)]
pub(crate) fn implicit_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    iterations: u32,
    scratch: &mut ImplicitScratch,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
) {
    let nf = model.n_free;
    let h2 = h * h;
    // Assembles b_i, the diagonal block of P and (when `blocks` is given) every link's
    // h c I + h² Kp block for free mass k.
    let assemble = |k: usize, blocks: Option<&mut [Sym3]>| -> (Vec3A, Sym3) {
        let (xi, vi) = (x[k], v[k]);
        let mut f = external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi);
        let mut kv = Vec3A::ZERO;
        let kr = model.restoring_stiffness(k, fe.restoring_w);
        let mut diag = Sym3::scaled_identity(model.mass[k] + h2 * kr);
        if kr > 0.0 {
            kv -= (vi - v[model.rest_parent[k] as usize]) * kr;
        }
        let base = model.adj_start[k] as usize;
        let adj = model.adj_of(k);
        let mut blocks = blocks;
        for (e, a) in adj.iter().enumerate() {
            let j = a.other as usize;
            let dv = v[j] - vi;
            let (fl, kp) = force_and_block(x[j] - xi, dv, a.rest, a.k, a.c);
            f += fl;
            kv += kp.mul(dv);
            let mut hb = Sym3::scaled_identity(h * a.c);
            hb.add_scaled(&kp, h2);
            diag.add_scaled(&hb, model.adj_weight[base + e]);
            if let Some(bl) = blocks.as_deref_mut() {
                bl[e] = hb;
            }
        }
        ((f + kv * h) * h, diag)
    };
    if iterations <= 1 && !model.has_tree() {
        // One sweep without trees: each link's force and block once, then per mass a gather
        // and one 3×3 solve.
        link_jacobians(model, h, x, v, &mut scratch.link_jac);
        let jac = &scratch.link_jac;
        for_free(nf, x_out, v_out, |k| {
            let (xi, vi) = (x[k], v[k]);
            let f = external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi);
            let mut kv = Vec3A::ZERO;
            let kr = model.restoring_stiffness(k, fe.restoring_w);
            let mut diag = Sym3::scaled_identity(model.mass[k] + h2 * kr);
            if kr > 0.0 {
                kv -= (vi - v[model.rest_parent[k] as usize]) * kr;
            }
            let mut ga = Vec3A::ZERO;
            for j in &jac[model.sa_start[k] as usize..model.sa_start[k + 1] as usize] {
                ga += j.g;
                for q in 0..6 {
                    diag.0[q] += j.hb[q];
                }
            }
            let mut gb = Vec3A::ZERO;
            for &sp in &model.gb_link[model.gb_start[k] as usize..model.gb_start[k + 1] as usize] {
                let j = &jac[sp as usize];
                gb += j.g;
                for q in 0..6 {
                    diag.0[q] += j.hb[q];
                }
            }
            let b = (f + kv * h + (ga - gb)) * h;
            let vn = vi + diag.solve(b);
            (xi + vn * h, vn)
        });
        project_sticks(model, x_out, v_out);
        return;
    }
    let s = scratch;
    s.b.resize(nf, Vec3A::ZERO);
    s.diag.resize(nf, Sym3::default());
    s.blocks.resize(model.adj.len(), Sym3::default());
    s.dv.clear();
    s.dv.resize(nf, Vec3A::ZERO);
    s.res.resize(nf, Vec3A::ZERO);
    {
        let mut block_slices: Vec<&mut [Sym3]> = Vec::with_capacity(nf);
        let mut rest = s.blocks.as_mut_slice();
        for k in 0..nf {
            let len = (model.adj_start[k + 1] - model.adj_start[k]) as usize;
            let (head, tail) = rest.split_at_mut(len);
            block_slices.push(head);
            rest = tail;
        }
        let work = |(k, ((b, d), bl)): (usize, ((&mut Vec3A, &mut Sym3), &mut &mut [Sym3]))| {
            let (bb, dd) = assemble(k, Some(&mut **bl));
            *b = bb;
            *d = dd;
        };
        if nf < PARALLEL_MIN {
            s.b.iter_mut().zip(s.diag.iter_mut()).zip(block_slices.iter_mut()).enumerate().for_each(work);
        } else {
            s.b.par_iter_mut()
                .zip(s.diag.par_iter_mut())
                .zip(block_slices.par_iter_mut())
                .enumerate()
                .with_min_len(CHUNK)
                .for_each(work);
        }
    }
    let tree = model.has_tree();
    if tree {
        // Factor P along the hair trees, deepest level first: D'_k = D_k − Σ_c H_c D'_c⁻¹ H_c.
        s.dinv.resize(nf, DMat3::ZERO);
        for &(ls, le) in model.levels.iter().rev() {
            for k in ls..le {
                let mut d = sym_to_dmat(&s.diag[k]);
                let (cs, ce) = (model.tree_children_start[k] as usize, model.tree_children_start[k + 1] as usize);
                for &c in &model.tree_children[cs..ce] {
                    let hc = sym_to_dmat(&s.blocks[model.tree_parent_adj[c as usize] as usize]);
                    d -= hc * s.dinv[c as usize] * hc;
                }
                s.dinv[k] = if d.determinant() > 0.0 { d.inverse() } else { DMat3::NAN };
            }
        }
        s.rp.resize(nf, DVec3::ZERO);
        s.z.resize(nf, DVec3::ZERO);
    }
    for it in 0..iterations {
        // Residual b − A Δv (Δv = 0 on the first sweep).
        if it == 0 {
            s.res.copy_from_slice(&s.b);
        } else {
            let (b, blocks, dv) = (&s.b, &s.blocks, &s.dv);
            let residual = |k: usize| -> Vec3A {
                let kr = model.restoring_stiffness(k, fe.restoring_w);
                let mut ax = dv[k] * (model.mass[k] + h2 * kr);
                let base = model.adj_start[k] as usize;
                for (e, a) in model.adj_of(k).iter().enumerate() {
                    let j = a.other as usize;
                    let dvj = if j < nf { dv[j] } else { Vec3A::ZERO };
                    ax += blocks[base + e].mul(dv[k] - dvj);
                }
                b[k] - ax
            };
            if nf < PARALLEL_MIN {
                for (k, o) in s.res.iter_mut().enumerate() {
                    *o = residual(k);
                }
            } else {
                s.res.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(k, o)| *o = residual(k));
            }
        }
        // Δv += P⁻¹ res.
        if !tree {
            let (diag, res) = (&s.diag, &s.res);
            if nf < PARALLEL_MIN {
                for (k, o) in s.dv.iter_mut().enumerate() {
                    *o += diag[k].solve(res[k]);
                }
            } else {
                s.dv.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(k, o)| *o += diag[k].solve(res[k]));
            }
        } else {
            for k in 0..nf {
                s.rp[k] = s.res[k].as_dvec3();
            }
            for &(ls, le) in model.levels.iter().rev() {
                for k in ls..le {
                    let (cs, ce) = (model.tree_children_start[k] as usize, model.tree_children_start[k + 1] as usize);
                    for &c in &model.tree_children[cs..ce] {
                        let c = c as usize;
                        let hc = sym_to_dmat(&s.blocks[model.tree_parent_adj[c] as usize]);
                        let add = hc * (s.dinv[c] * s.rp[c]);
                        s.rp[k] += add;
                    }
                }
            }
            for &(ls, le) in &model.levels {
                for k in ls..le {
                    let mut t = s.rp[k];
                    let p = model.tree_parent[k];
                    if p != NONE {
                        t += sym_to_dmat(&s.blocks[model.tree_parent_adj[k] as usize]) * s.z[p as usize];
                    }
                    s.z[k] = s.dinv[k] * t;
                }
            }
            for k in 0..nf {
                s.dv[k] += s.z[k].as_vec3a();
            }
        }
    }
    let dv = &s.dv;
    for_free(nf, x_out, v_out, |k| {
        let vn = v[k] + dv[k];
        (x[k] + vn * h, vn)
    });
    project_sticks(model, x_out, v_out);
}

/// One chunk of the reference assembly's outputs: right-hand sides, preconditioner blocks,
/// restoring stiffnesses and the chunk's link blocks.
type AssemblyChunk<'a> = (((&'a mut [DVec3], &'a mut [[f64; 9]]), &'a mut [f64]), &'a mut [[f64; 6]]);

/// Scratch of the converged reference solver (f64).
#[derive(Default)]
pub(crate) struct ReferenceScratch {
    b: Vec<DVec3>,
    pinv: Vec<[f64; 9]>,
    blocks: Vec<[f64; 6]>,
    kr: Vec<f64>,
    cg: Vec<CgRow>,
    p: Vec<DVec3>,
    ap: Vec<DVec3>,
}

/// Per free mass: CG solution, residual and preconditioned residual.
#[derive(Clone, Copy, Default)]
struct CgRow {
    x: DVec3,
    r: DVec3,
    z: DVec3,
}

#[inline(always)]
fn sym_mul64(m: &[f64; 6], v: DVec3) -> DVec3 {
    DVec3::new(
        m[0] * v.x + m[3] * v.y + m[4] * v.z,
        m[3] * v.x + m[1] * v.y + m[5] * v.z,
        m[4] * v.x + m[5] * v.y + m[2] * v.z,
    )
}

#[inline(always)]
fn precond(pinv: &[f64; 9], r: DVec3) -> DVec3 {
    DVec3::new(
        pinv[0] * r.x + pinv[1] * r.y + pinv[2] * r.z,
        pinv[3] * r.x + pinv[4] * r.y + pinv[5] * r.z,
        pinv[6] * r.x + pinv[7] * r.y + pinv[8] * r.z,
    )
}

/// Runs `f(chunk, out_chunk)` over the fixed `CHUNK`-mass chunks of `out` (parallel above the
/// cut-off) and returns the results in chunk order, so sums over them are thread-count independent.
fn chunk_map<T: Send, R: Send, F: Fn(usize, &mut [T]) -> R + Sync>(out: &mut [T], f: F) -> Vec<R> {
    if out.len() < PARALLEL_MIN {
        out.chunks_mut(CHUNK).enumerate().map(|(c, o)| f(c, o)).collect()
    } else {
        out.par_chunks_mut(CHUNK).enumerate().map(|(c, o)| f(c, o)).collect()
    }
}

/// One converged backward-Euler step: PCG on the linearised system to relative residual `tol`.
/// Returns the CG iterations used and the relative residual reached.
#[allow(clippy::too_many_arguments)]
pub(crate) fn reference_step(
    model: &SimModel,
    fe: &ForceEval,
    h: f32,
    tol: f64,
    max_iterations: u32,
    s: &mut ReferenceScratch,
    x: &[Vec3A],
    v: &[Vec3A],
    x_out: &mut [Vec3A],
    v_out: &mut [Vec3A],
) -> (u32, f64) {
    let nf = model.n_free;
    let hd = h as f64;
    let h2 = hd * hd;
    s.blocks.resize(model.adj.len(), [0.0; 6]);
    s.b.resize(nf, DVec3::ZERO);
    s.pinv.resize(nf, [0.0; 9]);
    s.kr.resize(nf, 0.0);
    // Assembly, per mass over its own links, in parallel over fixed chunks of masses (each chunk
    // writes its masses' slice of `blocks`).
    {
        let mut block_chunks: Vec<&mut [[f64; 6]]> = Vec::with_capacity(nf.div_ceil(CHUNK));
        let mut rest = s.blocks.as_mut_slice();
        let mut prev = 0usize;
        for c in 0..nf.div_ceil(CHUNK) {
            let end = model.adj_start[((c + 1) * CHUNK).min(nf)] as usize;
            let (head, tail) = rest.split_at_mut(end - prev);
            block_chunks.push(head);
            rest = tail;
            prev = end;
        }
        let assemble = |k: usize, blocks: &mut [[f64; 6]]| -> (DVec3, [f64; 9], f64) {
            let kr = model.restoring_stiffness(k, fe.restoring_w) as f64;
            let (xi, vi) = (x[k], v[k]);
            let mut f = (external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi)).as_dvec3();
            let mut kv = DVec3::ZERO;
            if kr > 0.0 {
                kv -= (vi - v[model.rest_parent[k] as usize]).as_dvec3() * kr;
            }
            let md = model.mass[k] as f64 + h2 * kr;
            let mut diag = [md, md, md, 0.0, 0.0, 0.0];
            for (e, a) in model.adj_of(k).iter().enumerate() {
                let j = a.other as usize;
                let (xj, vj) = (x[j].as_dvec3(), v[j].as_dvec3());
                let d = xj - xi.as_dvec3();
                let l = d.length();
                let (rest, kk, c) = (a.rest as f64, a.k as f64, a.c as f64);
                f += d * (kk * (1.0 - rest / l.max(1e-300))) + (vj - vi.as_dvec3()) * c;
                let kp: [f64; 6] = if kk == 0.0 {
                    [0.0; 6]
                } else if l <= 1e-12 {
                    let s = if rest == 0.0 { kk } else { 0.0 };
                    [s, s, s, 0.0, 0.0, 0.0]
                } else {
                    let beta = (1.0 - rest / l).clamp(0.0, 1.0);
                    let u = d / l;
                    let g = kk * (1.0 - beta);
                    let kb = kk * beta;
                    [
                        kb + g * u.x * u.x,
                        kb + g * u.y * u.y,
                        kb + g * u.z * u.z,
                        g * u.x * u.y,
                        g * u.x * u.z,
                        g * u.y * u.z,
                    ]
                };
                kv += sym_mul64(&kp, vj - vi.as_dvec3());
                let mut hb = kp.map(|q| q * h2);
                for q in &mut hb[..3] {
                    *q += hd * c;
                }
                for q in 0..6 {
                    diag[q] += hb[q];
                }
                blocks[e] = hb;
            }
            // Block-Jacobi preconditioner: the inverse of the diagonal block.
            let (a, ee, i, bb, c, ff) = (diag[0], diag[1], diag[2], diag[3], diag[4], diag[5]);
            let (c00, c01, c02) = (ee * i - ff * ff, c * ff - bb * i, bb * ff - c * ee);
            let (c11, c12, c22) = (a * i - c * c, bb * c - a * ff, a * ee - bb * bb);
            let det = a * c00 + bb * c01 + c * c02;
            let r = if det > 0.0 && det.is_finite() { 1.0 / det } else { 0.0 };
            let pinv = [c00 * r, c01 * r, c02 * r, c01 * r, c11 * r, c12 * r, c02 * r, c12 * r, c22 * r];
            ((f + kv * hd) * hd, pinv, kr)
        };
        let work = |(c, (((bc, pc), kc), blc)): (usize, AssemblyChunk)| {
            let base = model.adj_start[c * CHUNK] as usize;
            for o in 0..bc.len() {
                let k = c * CHUNK + o;
                let (s0, s1) = (model.adj_start[k] as usize - base, model.adj_start[k + 1] as usize - base);
                (bc[o], pc[o], kc[o]) = assemble(k, &mut blc[s0..s1]);
            }
        };
        if nf < PARALLEL_MIN {
            s.b.chunks_mut(CHUNK)
                .zip(s.pinv.chunks_mut(CHUNK))
                .zip(s.kr.chunks_mut(CHUNK))
                .zip(block_chunks)
                .enumerate()
                .for_each(work);
        } else {
            s.b.par_chunks_mut(CHUNK)
                .zip(s.pinv.par_chunks_mut(CHUNK))
                .zip(s.kr.par_chunks_mut(CHUNK))
                .zip(block_chunks.into_par_iter())
                .enumerate()
                .for_each(work);
        }
    }
    let (blocks, kr, pinv, b) = (&s.blocks, &s.kr, &s.pinv, &s.b);
    let apply_a = |xs: &[DVec3], k: usize| -> DVec3 {
        let xk = xs[k];
        let mut y = xk * (model.mass[k] as f64 + h2 * kr[k]);
        let (s0, s1) = (model.adj_start[k] as usize, model.adj_start[k + 1] as usize);
        for (&j, blk) in model.adj_other[s0..s1].iter().zip(&blocks[s0..s1]) {
            let j = j as usize;
            let xj = if j < nf { xs[j] } else { DVec3::ZERO };
            y += sym_mul64(blk, xk - xj);
        }
        y
    };
    s.cg.resize(nf, CgRow::default());
    s.p.resize(nf, DVec3::ZERO);
    s.ap.resize(nf, DVec3::ZERO);
    // Initial state x = 0, r = b, z = P⁻¹ r, p = z; sums of b·b and r·z per chunk.
    let sums = chunk_map(&mut s.cg, |c, rows| {
        let mut acc = [0.0f64; 2];
        for (o, row) in rows.iter_mut().enumerate() {
            let k = c * CHUNK + o;
            let r = b[k];
            let z = precond(&pinv[k], r);
            *row = CgRow { x: DVec3::ZERO, r, z };
            acc[0] += r.length_squared();
            acc[1] += r.dot(z);
        }
        acc
    });
    let sum = |v: &[[f64; 2]], i: usize| v.iter().fold(0.0, |a, s| a + s[i]);
    let bnorm = sum(&sums, 0).sqrt();
    let mut rz = sum(&sums, 1);
    let mut iterations = 0;
    let mut rel = 0.0;
    if bnorm > 0.0 {
        {
            let cg = &s.cg;
            for (p, row) in s.p.iter_mut().zip(cg) {
                *p = row.z;
            }
        }
        rel = 1.0;
        loop {
            if rel <= tol || iterations >= max_iterations {
                break;
            }
            iterations += 1;
            // ap = A p and p·ap.
            let pap: f64 = {
                let p = &s.p;
                chunk_map(&mut s.ap, |c, out| {
                    let mut acc = 0.0f64;
                    for (o, y) in out.iter_mut().enumerate() {
                        let k = c * CHUNK + o;
                        *y = apply_a(p, k);
                        acc += p[k].dot(*y);
                    }
                    acc
                })
                .iter()
                .fold(0.0, |a, s| a + s)
            };
            if pap.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                break;
            }
            let alpha = rz / pap;
            // x += α p, r −= α ap, z = P⁻¹ r, with r·r and r·z.
            let sums = {
                let (p, ap) = (&s.p, &s.ap);
                chunk_map(&mut s.cg, |c, rows| {
                    let mut acc = [0.0f64; 2];
                    for (o, row) in rows.iter_mut().enumerate() {
                        let k = c * CHUNK + o;
                        row.x += p[k] * alpha;
                        row.r -= ap[k] * alpha;
                        row.z = precond(&pinv[k], row.r);
                        acc[0] += row.r.length_squared();
                        acc[1] += row.r.dot(row.z);
                    }
                    acc
                })
            };
            rel = sum(&sums, 0).sqrt() / bnorm;
            let rz_new = sum(&sums, 1);
            let beta = rz_new / rz;
            rz = rz_new;
            {
                let cg = &s.cg;
                chunk_map(&mut s.p, |c, out| {
                    for (o, p) in out.iter_mut().enumerate() {
                        *p = cg[c * CHUNK + o].z + *p * beta;
                    }
                });
            }
        }
    }
    let cg = &s.cg;
    for_free(nf, x_out, v_out, |k| {
        let vn = (v[k].as_dvec3() + cg[k].x).as_vec3a();
        ((x[k].as_dvec3() + vn.as_dvec3() * hd).as_vec3a(), vn)
    });
    project_sticks(model, x_out, v_out);
    (iterations, rel)
}
