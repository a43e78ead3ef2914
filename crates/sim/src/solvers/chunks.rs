//! Fixed-chunk parallel loops and sums: every per-mass loop of the solvers runs over fixed
//! `CHUNK`-mass chunks (in parallel above `PARALLEL_MIN` free masses), and every sum adds its
//! chunks' partial sums in chunk order, so every result — positions, CG dot products, energies —
//! is bit-identical for any rayon thread count.

use glam::Vec3A;
use rayon::prelude::*;

/// Masses per parallel work item; also the fixed chunk of deterministic sums.
pub(crate) const CHUNK: usize = 1024;
/// Below this many free masses the kernels run on the calling thread.
pub(crate) const PARALLEL_MIN: usize = 4096;

/// Runs `f(k)` for every free mass `k`, writing the returned `(x, v)` to `x_out[k]`, `v_out[k]`.
pub(super) fn for_free<F>(n_free: usize, x_out: &mut [Vec3A], v_out: &mut [Vec3A], f: F)
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

/// Runs `f(chunk, out_chunk)` over the fixed `CHUNK`-element chunks of `out` (parallel above
/// the cut-off).
pub(super) fn chunk_for_each<T: Send, F: Fn(usize, &mut [T]) + Sync>(out: &mut [T], f: F) {
    if out.len() < PARALLEL_MIN {
        out.chunks_mut(CHUNK).enumerate().for_each(|(c, o)| f(c, o));
    } else {
        out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, o)| f(c, o));
    }
}

/// Runs `f(chunk, out_chunk)` over the fixed `CHUNK`-mass chunks of `out` (parallel above the
/// cut-off), keeps each chunk's partial sum in `sums` (scratch: no allocation once sized) and
/// returns their sums in chunk order, so it is thread-count independent.
pub(super) fn chunk_sum<T: Send, const N: usize, F: Fn(usize, &mut [T]) -> [f64; N] + Sync>(
    out: &mut [T],
    sums: &mut Vec<[f64; N]>,
    f: F,
) -> [f64; N] {
    sums.resize(out.len().div_ceil(CHUNK), [0.0; N]);
    if out.len() < PARALLEL_MIN {
        for (c, (o, s)) in out.chunks_mut(CHUNK).zip(sums.iter_mut()).enumerate() {
            *s = f(c, o);
        }
    } else {
        out.par_chunks_mut(CHUNK).zip(sums.par_iter_mut()).enumerate().for_each(|(c, (o, s))| *s = f(c, o));
    }
    sums.iter().fold([0.0; N], |mut a, s| {
        for (a, s) in a.iter_mut().zip(s) {
            *a += s;
        }
        a
    })
}
