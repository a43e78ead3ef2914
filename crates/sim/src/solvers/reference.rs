//! The converged reference solver (Baraff & Witkin 1998): the same linearised backward-Euler
//! system as the implicit solver (fur thesis eq. 3.26–3.29) without its diagonal trick, in f64,
//! solved by block-Jacobi-preconditioned conjugate gradient to a tight relative residual. The
//! accuracy report measures every other solver against it.
//!
//! The system is assembled in parallel per mass (links to anchored masses folded into the mass's
//! own block) and CG runs two passes per iteration: `p = z + βp`, `Ap = Az + βAp` and `p·Ap` in
//! one; the vector updates, the preconditioner and the two dot products in the other. Every dot
//! product sums fixed chunks in order (`chunks.rs`). The new state, stick projection, guard and
//! rotation limit then run in the fused lane-group pass (`fused.rs`).

use glam::DVec3;
use rayon::prelude::*;

use super::chunks::{CHUNK, PARALLEL_MIN, chunk_map, chunk_map2, for_free};
use super::fused::{Mode, finish_step, group_step};
use super::stick::project_sticks;
use super::{Step, StepOutcome};
use super::{external, restoring};
use crate::model::SimModel;

/// One chunk of the reference assembly's outputs: right-hand sides, preconditioner blocks,
/// own blocks and the chunk's link blocks.
type AssemblyChunk<'a> = (((&'a mut [DVec3], &'a mut [[f64; 6]]), &'a mut [[f64; 6]]), &'a mut [[f64; 6]]);

/// Scratch of the converged reference solver (f64).
#[derive(Default)]
pub(crate) struct ReferenceScratch {
    /// Per free mass the right-hand side `h (F + h ∂F/∂x v)`.
    b: Vec<DVec3>,
    /// Inverse diagonal blocks (symmetric, `[xx, yy, zz, xy, xz, yz]`).
    pinv: Vec<[f64; 6]>,
    /// The `h c I + h² Kp` blocks of the links between free masses, one per link (`ref_slot`).
    blocks: Vec<[f64; 6]>,
    /// Per free mass its own block: mass, restoring stiffness and its links to anchored masses.
    dself: Vec<[f64; 6]>,
    cg: Vec<CgRow>,
    /// Preconditioned residual.
    z: Vec<DVec3>,
    /// Search direction `p` and `A p`.
    pap: Vec<[DVec3; 2]>,
}

/// Per free mass: CG solution and residual.
#[derive(Clone, Copy, Default)]
pub(super) struct CgRow {
    pub x: DVec3,
    pub r: DVec3,
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
fn precond(pinv: &[f64; 6], r: DVec3) -> DVec3 {
    sym_mul64(pinv, r)
}

/// What a reference step did: the CG iterations used, the relative residual reached and what
/// the end of the step did.
pub(crate) struct ReferenceOutcome {
    pub iterations: u32,
    pub residual: f64,
    pub step: StepOutcome,
}

/// One converged backward-Euler step: PCG on the linearised system to relative residual `tol`,
/// at most `max_iterations` iterations. A step that does not converge is rejected: the guard
/// is left alone and the caller reports [`ReferenceOutcome::residual`].
pub(crate) fn reference_step(step: Step, tol: f64, max_iterations: u32, s: &mut ReferenceScratch) -> ReferenceOutcome {
    assemble_system(&step, s);
    let (iterations, residual) = solve_cg(step.model, tol, max_iterations, s);
    let converged = !(residual > tol && residual.is_finite());
    ReferenceOutcome { iterations, residual, step: finish_reference_step(step, &s.cg, converged) }
}

/// Free mass `k`'s right-hand side `h (F + h ∂F/∂x v)`, its block-Jacobi preconditioner (the
/// inverse of its diagonal block) and its own block (mass, restoring stiffness and its links to
/// anchored masses); writes the blocks of the links to free masses that `k` owns into `blocks`
/// (the chunk's slice, whose first slot is `base`).
#[inline]
fn assemble_mass(step: &Step, k: usize, blocks: &mut [[f64; 6]], base: usize) -> (DVec3, [f64; 6], [f64; 6]) {
    let (model, fe, x, v) = (step.model, step.fe, step.x, step.v);
    let hd = step.h as f64;
    let h2 = hd * hd;
    let kr = model.restoring_stiffness(k, fe.restoring_w) as f64;
    let (xi, vi) = (x[k], v[k]);
    let mut f = (external(model, fe, k, xi, vi) + restoring(model, fe, x, k, xi)).as_dvec3();
    let mut kv = DVec3::ZERO;
    if kr > 0.0 {
        kv -= (vi - v[model.rest_parent[k] as usize]).as_dvec3() * kr;
    }
    let md = model.mass[k] as f64 + h2 * kr;
    let mut diag = [md, md, md, 0.0, 0.0, 0.0];
    let mut dself = diag;
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
            [kb + g * u.x * u.x, kb + g * u.y * u.y, kb + g * u.z * u.z, g * u.x * u.y, g * u.x * u.z, g * u.y * u.z]
        };
        kv += sym_mul64(&kp, vj - vi.as_dvec3());
        let mut hb = kp.map(|q| q * h2);
        for q in &mut hb[..3] {
            *q += hd * c;
        }
        for q in 0..6 {
            diag[q] += hb[q];
        }
        let ae = model.adj_start[k] as usize + e;
        if j >= model.n_free {
            for q in 0..6 {
                dself[q] += hb[q];
            }
        } else if model.ref_owner[ae] {
            blocks[model.ref_slot[ae] as usize - base] = hb;
        }
    }
    // Block-Jacobi preconditioner: the inverse of the diagonal block.
    let (a, ee, i, bb, c, ff) = (diag[0], diag[1], diag[2], diag[3], diag[4], diag[5]);
    let (c00, c01, c02) = (ee * i - ff * ff, c * ff - bb * i, bb * ff - c * ee);
    let (c11, c12, c22) = (a * i - c * c, bb * c - a * ff, a * ee - bb * bb);
    let det = a * c00 + bb * c01 + c * c02;
    let r = if det > 0.0 && det.is_finite() { 1.0 / det } else { 0.0 };
    let pinv = [c00 * r, c11 * r, c22 * r, c01 * r, c02 * r, c12 * r];
    ((f + kv * hd) * hd, pinv, dself)
}

/// Sizes the scratch and assembles the system ([`assemble_mass`]), per mass over its own links,
/// in parallel over fixed chunks of masses (each chunk writes the blocks of the links between
/// free masses that its masses list first — the other end computes the same block bit for bit
/// and only adds it to its diagonal).
fn assemble_system(step: &Step, s: &mut ReferenceScratch) {
    let model = step.model;
    let nf = model.n_free;
    s.blocks.resize(model.ref_first[nf] as usize, [0.0; 6]);
    s.b.resize(nf, DVec3::ZERO);
    s.pinv.resize(nf, [0.0; 6]);
    s.dself.resize(nf, [0.0; 6]);
    let mut block_chunks: Vec<&mut [[f64; 6]]> = Vec::with_capacity(nf.div_ceil(CHUNK));
    let mut rest = s.blocks.as_mut_slice();
    let mut prev = 0usize;
    for c in 0..nf.div_ceil(CHUNK) {
        let end = model.ref_first[((c + 1) * CHUNK).min(nf)] as usize;
        let (head, tail) = rest.split_at_mut(end - prev);
        block_chunks.push(head);
        rest = tail;
        prev = end;
    }
    let work = |(c, (((bc, pc), kc), blc)): (usize, AssemblyChunk)| {
        let base = model.ref_first[c * CHUNK] as usize;
        for o in 0..bc.len() {
            let k = c * CHUNK + o;
            (bc[o], pc[o], kc[o]) = assemble_mass(step, k, blc, base);
        }
    };
    if nf < PARALLEL_MIN {
        s.b.chunks_mut(CHUNK)
            .zip(s.pinv.chunks_mut(CHUNK))
            .zip(s.dself.chunks_mut(CHUNK))
            .zip(block_chunks)
            .enumerate()
            .for_each(work);
    } else {
        s.b.par_chunks_mut(CHUNK)
            .zip(s.pinv.par_chunks_mut(CHUNK))
            .zip(s.dself.par_chunks_mut(CHUNK))
            .zip(block_chunks.into_par_iter())
            .enumerate()
            .for_each(work);
    }
}

/// Row `k` of `A y`: the mass's own block (mass, restoring stiffness and its links to anchored
/// masses) times `y_k`, plus every link to a free mass times `(y_k − y_j)`.
#[inline]
fn apply_a(model: &SimModel, blocks: &[[f64; 6]], dself: &[[f64; 6]], ys: &[DVec3], k: usize) -> DVec3 {
    let nf = model.n_free;
    let yk = ys[k];
    let mut y = sym_mul64(&dself[k], yk);
    let (s0, s1) = (model.adj_start[k] as usize, model.adj_start[k + 1] as usize);
    for (&j, &slot) in model.adj_other[s0..s1].iter().zip(&model.ref_slot[s0..s1]) {
        let j = j as usize;
        if j < nf {
            y += sym_mul64(&blocks[slot as usize], yk - ys[j]);
        }
    }
    y
}

/// Preconditioned CG on the assembled system from `Δv = 0` until the relative residual is at most
/// `tol` or `max_iterations` are used; the solution in `s.cg[k].x`. Returns the iterations used
/// and the relative residual reached (0 for a zero right-hand side).
fn solve_cg(model: &SimModel, tol: f64, max_iterations: u32, s: &mut ReferenceScratch) -> (u32, f64) {
    let nf = model.n_free;
    let (blocks, dself, pinv, b) = (&s.blocks, &s.dself, &s.pinv, &s.b);
    s.cg.resize(nf, CgRow::default());
    s.z.resize(nf, DVec3::ZERO);
    s.pap.resize(nf, [DVec3::ZERO; 2]);
    // Initial state x = 0, r = b, z = P⁻¹ r; sums of b·b and r·z per chunk.
    let sums = chunk_map2(&mut s.cg, &mut s.z, |c, rows, zs| {
        let mut acc = [0.0f64; 2];
        for (o, (row, zo)) in rows.iter_mut().zip(zs.iter_mut()).enumerate() {
            let k = c * CHUNK + o;
            let r = b[k];
            let z = precond(&pinv[k], r);
            (*row, *zo) = (CgRow { x: DVec3::ZERO, r }, z);
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
        rel = 1.0;
        let mut beta = None;
        loop {
            if rel <= tol || iterations >= max_iterations {
                break;
            }
            iterations += 1;
            // p = z + β p and A p = A z + β A p (so the product needs only z, final everywhere
            // after the last pass), with p·Ap; p = z on the first iteration.
            let pap: f64 = {
                let z = &s.z;
                chunk_map(&mut s.pap, |c, out| {
                    let mut acc = 0.0f64;
                    for (o, pa) in out.iter_mut().enumerate() {
                        let k = c * CHUNK + o;
                        let az = apply_a(model, blocks, dself, z, k);
                        *pa = match beta {
                            None => [z[k], az],
                            Some(beta) => [z[k] + pa[0] * beta, az + pa[1] * beta],
                        };
                        acc += pa[0].dot(pa[1]);
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
                let pa = &s.pap;
                chunk_map2(&mut s.cg, &mut s.z, |c, rows, zs| {
                    let mut acc = [0.0f64; 2];
                    for (o, (row, zo)) in rows.iter_mut().zip(zs.iter_mut()).enumerate() {
                        let k = c * CHUNK + o;
                        row.x += pa[k][0] * alpha;
                        row.r -= pa[k][1] * alpha;
                        *zo = precond(&pinv[k], row.r);
                        acc[0] += row.r.length_squared();
                        acc[1] += row.r.dot(*zo);
                    }
                    acc
                })
            };
            rel = sum(&sums, 0).sqrt() / bnorm;
            let rz_new = sum(&sums, 1);
            beta = Some(rz_new / rz);
            rz = rz_new;
        }
    }
    (iterations, rel)
}

/// The end of a reference step from the CG solution `cg`: when it `converged`, the new state,
/// projection, check, guard and rotation limit in one lane-group pass where the topology allows,
/// else the new state and [`finish_step`]; when it did not, the new state and the projection
/// only (the guard left alone).
fn finish_reference_step(step: Step, cg: &[CgRow], converged: bool) -> StepOutcome {
    let model = step.model;
    if converged && (!model.has_sticks || model.sticks_to_anchors) {
        return group_step(step, Mode::Finish, cg);
    }
    let (x, v, hd) = (step.x, step.v, step.h as f64);
    for_free(model.n_free, step.x_out, step.v_out, |k| {
        let vn = (v[k].as_dvec3() + cg[k].x).as_vec3a();
        ((x[k].as_dvec3() + vn.as_dvec3() * hd).as_vec3a(), vn)
    });
    if converged {
        finish_step(step)
    } else {
        project_sticks(model, step.x_out, step.v_out);
        StepOutcome { finite: false, guard: None, rotation: None }
    }
}
