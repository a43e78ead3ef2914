//! The implicit solvers' rotation-limited step (a stability limit on top of the fur thesis's
//! eq. 3.26–3.34): linearised implicit Euler turns large rotations into stretch and can add
//! energy, so a step is split where a free mass would turn its shortest link by more than `θ`:
//! per mass the `h` with `|v| h + |a| h² = θ · shortest link`, `a` the external (and restoring,
//! eq. 3.37) acceleration, in f64; the smallest over the free masses, in fixed chunks, eight
//! masses at a time in AVX lanes when the forces are uniform. The fused pass (`fused.rs`)
//! computes the same value from the new state when it can.

use glam::Vec3A;
use rayon::prelude::*;

use super::chunks::{CHUNK, PARALLEL_MIN};
use super::external;
#[cfg(target_arch = "x86_64")]
use super::lanes::{Avx, Lanes, dot3, map3, rotation_step};
use crate::forces::ForceEval;
#[cfg(target_arch = "x86_64")]
use crate::groups::GROUP;
use crate::model::SimModel;

/// One free mass's rotation-limited step (see `Simulator::rotation_limited_step_s`): the `h` with
/// `|v| h + |a| h² = θ · shortest link`, `a` the external and restoring acceleration, in f64.
#[inline]
pub(super) fn rotation_limit_of(
    model: &SimModel,
    fe: &ForceEval,
    theta: f64,
    x: &[Vec3A],
    v: &[Vec3A],
    k: usize,
) -> f64 {
    let reach = theta * model.shortest_link[k] as f64;
    if !reach.is_finite() {
        return f64::INFINITY;
    }
    let f = external(model, fe, k, x[k], v[k]);
    let a = (f.length() + 4.0 * fe.restoring_w) as f64 / model.mass[k] as f64;
    rotation_step(v[k].length() as f64, a, reach)
}

/// The smallest [`rotation_limit_of`] over the masses `k0..k1` with only uniform forces, eight
/// masses at a time: the f32 parts (speeds, force magnitudes) in AVX lanes, the f64 parts four
/// lanes at a time — the same IEEE operations as [`rotation_limit_of`], so the same result.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn rotation_chunk_avx2(
    model: &SimModel,
    fe: &ForceEval,
    theta: f64,
    x: &[Vec3A],
    v: &[Vec3A],
    k0: usize,
    k1: usize,
) -> f64 {
    use std::arch::x86_64::*;
    let wv = Avx::splat(4.0 * fe.restoring_w);
    let acc = [Avx::splat(fe.accel.x), Avx::splat(fe.accel.y), Avx::splat(fe.accel.z)];
    let (t64, two, four, zero, inf) = (
        _mm256_set1_pd(theta),
        _mm256_set1_pd(2.0),
        _mm256_set1_pd(4.0),
        _mm256_setzero_pd(),
        _mm256_set1_pd(f64::INFINITY),
    );
    let mut best = inf;
    let mut k = k0;
    while k + GROUP <= k1 {
        let idx: [u32; GROUP] = std::array::from_fn(|l| (k + l) as u32);
        let vv = Avx::gather3(v, &idx);
        let vl = dot3(&vv, &vv).sqrt();
        let m32 = Avx::load(model.mass[k..k + GROUP].try_into().expect("eight masses"));
        let sl = Avx::load(model.shortest_link[k..k + GROUP].try_into().expect("eight masses"));
        let f = map3!(a => acc[a] * m32);
        let fa = dot3(&f, &f).sqrt() + wv;
        let halves =
            |q: Avx| [_mm256_cvtps_pd(_mm256_castps256_ps128(q.0)), _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(q.0))];
        let (vh, fh, mh, sh) = (halves(vl), halves(fa), halves(m32), halves(sl));
        for i in 0..2 {
            let (v, reach) = (vh[i], _mm256_mul_pd(t64, sh[i]));
            let a = _mm256_div_pd(fh[i], mh[i]);
            let root = _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(v, v), _mm256_mul_pd(_mm256_mul_pd(four, a), reach)));
            let h1 = _mm256_div_pd(_mm256_mul_pd(two, reach), _mm256_add_pd(v, root));
            let h2 = _mm256_div_pd(reach, v);
            let h2 = _mm256_blendv_pd(inf, h2, _mm256_cmp_pd::<_CMP_GT_OQ>(v, zero));
            let h = _mm256_blendv_pd(h2, h1, _mm256_cmp_pd::<_CMP_GT_OQ>(a, zero));
            let finite = _mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(reach, reach), zero);
            let h = _mm256_blendv_pd(inf, h, finite);
            // minpd keeps the second operand when the first is NaN: NaN is ignored, as f64::min.
            best = _mm256_min_pd(h, best);
        }
        k += GROUP;
    }
    let mut lanes = [0.0f64; 4];
    // SAFETY: `lanes` is four writable doubles (unaligned store); AVX is enabled here.
    unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), best) };
    let mut out = lanes.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    for kk in k..k1 {
        out = out.min(rotation_limit_of(model, fe, theta, x, v, kk));
    }
    out
}

/// The implicit solvers' rotation-limited step: the smallest [`rotation_limit_of`] over the free
/// masses (f64::min, so NaN is ignored), in fixed chunks.
pub(crate) fn rotation_limit(model: &SimModel, fe: &ForceEval, theta: f64, x: &[Vec3A], v: &[Vec3A]) -> f64 {
    let nf = model.n_free;
    let chunk = |c: usize| -> f64 {
        let (k0, k1) = (c * CHUNK, ((c + 1) * CHUNK).min(nf));
        #[cfg(target_arch = "x86_64")]
        if fe.uniform_only() && std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports AVX2 and FMA (detected just above).
            return unsafe { rotation_chunk_avx2(model, fe, theta, x, v, k0, k1) };
        }
        (k0..k1).map(|k| rotation_limit_of(model, fe, theta, x, v, k)).fold(f64::INFINITY, f64::min)
    };
    let chunks = nf.div_ceil(CHUNK);
    if nf < PARALLEL_MIN {
        (0..chunks).map(chunk).fold(f64::INFINITY, f64::min)
    } else {
        (0..chunks).into_par_iter().map(chunk).reduce(|| f64::INFINITY, f64::min)
    }
}
