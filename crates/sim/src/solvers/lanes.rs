//! The eight-lane SIMD layer of the fused pass (`fused.rs`, the fur thesis's eq. 3.20–3.29 per
//! mass): [`Lanes`], eight `f32` lanes with the operations the per-mass kernels need, as portable
//! arrays ([`Sc`]) and as an AVX register ([`Avx`], used only after runtime detection of AVX2 and
//! FMA); the three-component helpers ([`V3`], `map3!`, [`dot3`]) and the group loads ([`at`],
//! [`present`]). Eight consecutive free masses form one lane group ([`crate::groups::GroupData`]).

use std::ops::{Add, Div, Mul, Sub};

use glam::Vec3A;

use crate::groups::GROUP;
use crate::sentinel::NONE;

/// Eight `f32` lanes and the operations the per-mass kernels need. [`Sc`] is portable (plain
/// arrays, which the compiler vectorises as it can); [`Avx`] is an AVX register, used only after
/// runtime detection of AVX2 and FMA. Both perform the same IEEE operations in the same order,
/// except that [`Lanes::mul_add`] is fused on AVX (results may differ in the last bit between
/// the two; each is deterministic). Masks are lanes with every bit set (true) or clear (false).
pub(super) trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    fn splat(v: f32) -> Self;
    fn load(a: &[f32; GROUP]) -> Self;
    fn sqrt(self) -> Self;
    /// `self · b + c`: fused (one rounding) with AVX2+FMA, two roundings on the portable lanes.
    fn mul_add(self, b: Self, c: Self) -> Self;
    /// `self > o ? self : o` (the second operand when either is NaN, as `maxps`).
    fn max(self, o: Self) -> Self;
    /// `self < o ? self : o` (the second operand when either is NaN, as `minps`).
    fn min(self, o: Self) -> Self;
    /// Ordered `<=`, `==`, `>` and unordered `!=`, as masks.
    fn le(self, o: Self) -> Self;
    fn eq(self, o: Self) -> Self;
    fn gt(self, o: Self) -> Self;
    fn ne(self, o: Self) -> Self;
    /// Bitwise and (mask & value).
    fn and(self, o: Self) -> Self;
    /// `m ? a : b` lane by lane.
    fn select(m: Self, a: Self, b: Self) -> Self;
    /// Bit `l` set when lane `l`'s mask is true.
    fn bits(self) -> u32;
    /// Lowers `best` to the smallest rotation-limited step of eight masses (see
    /// `rotation_limit_of` in `rotation.rs`) from their speeds `vl`, force magnitudes plus `4w`
    /// `fa`, masses `m` and shortest links `sl` (f32 lanes), with the same f64 arithmetic.
    fn rot_min(vl: Self, fa: Self, m: Self, sl: Self, theta: f64, best: &mut f64);
    /// The eight vectors `src[idx[l]]`, by component.
    fn gather3(src: &[Vec3A], idx: &[u32; GROUP]) -> [Self; 3];
    /// The eight vectors of three component lanes.
    fn rows3(c: [Self; 3]) -> [Vec3A; GROUP];
    /// True lanes where the value is finite (`x − x` is 0 for finite `x`, NaN otherwise).
    #[inline(always)]
    #[allow(clippy::eq_op)]
    fn finite(self) -> Self {
        (self - self).eq(Self::splat(0.0))
    }
}

/// Portable lanes.
#[derive(Clone, Copy)]
pub(super) struct Sc(pub [f32; GROUP]);

macro_rules! sc_binop {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for Sc {
            type Output = Sc;
            #[inline(always)]
            fn $f(self, o: Sc) -> Sc {
                Sc(std::array::from_fn(|l| self.0[l] $op o.0[l]))
            }
        }
    };
}
sc_binop!(Add, add, +);
sc_binop!(Sub, sub, -);
sc_binop!(Mul, mul, *);
sc_binop!(Div, div, /);

impl Sc {
    #[inline(always)]
    fn mask(f: impl Fn(usize) -> bool) -> Sc {
        Sc(std::array::from_fn(|l| f32::from_bits(if f(l) { u32::MAX } else { 0 })))
    }
}

impl Lanes for Sc {
    #[inline(always)]
    fn splat(v: f32) -> Sc {
        Sc([v; GROUP])
    }
    #[inline(always)]
    fn load(a: &[f32; GROUP]) -> Sc {
        Sc(*a)
    }
    #[inline(always)]
    fn sqrt(self) -> Sc {
        Sc(self.0.map(f32::sqrt))
    }
    #[inline(always)]
    fn mul_add(self, b: Sc, c: Sc) -> Sc {
        self * b + c
    }
    #[inline(always)]
    fn max(self, o: Sc) -> Sc {
        Sc(std::array::from_fn(|l| if self.0[l] > o.0[l] { self.0[l] } else { o.0[l] }))
    }
    #[inline(always)]
    fn min(self, o: Sc) -> Sc {
        Sc(std::array::from_fn(|l| if self.0[l] < o.0[l] { self.0[l] } else { o.0[l] }))
    }
    #[inline(always)]
    fn le(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] <= o.0[l])
    }
    #[inline(always)]
    fn eq(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] == o.0[l])
    }
    #[inline(always)]
    fn gt(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] > o.0[l])
    }
    #[inline(always)]
    fn ne(self, o: Sc) -> Sc {
        Sc::mask(|l| self.0[l] != o.0[l])
    }
    #[inline(always)]
    fn and(self, o: Sc) -> Sc {
        Sc(std::array::from_fn(|l| f32::from_bits(self.0[l].to_bits() & o.0[l].to_bits())))
    }
    #[inline(always)]
    fn select(m: Sc, a: Sc, b: Sc) -> Sc {
        Sc(std::array::from_fn(|l| if m.0[l].to_bits() != 0 { a.0[l] } else { b.0[l] }))
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        (0..GROUP).fold(0, |b, l| b | (((self.0[l].to_bits() >> 31) & 1) << l))
    }
    #[inline(always)]
    fn rot_min(vl: Sc, fa: Sc, m: Sc, sl: Sc, theta: f64, best: &mut f64) {
        for l in 0..GROUP {
            *best = best.min(rotation_step(vl.0[l] as f64, fa.0[l] as f64 / m.0[l] as f64, theta * sl.0[l] as f64));
        }
    }
    #[inline(always)]
    fn gather3(src: &[Vec3A], idx: &[u32; GROUP]) -> [Sc; 3] {
        let r: [Vec3A; GROUP] = std::array::from_fn(|l| src[idx[l] as usize]);
        [Sc(r.map(|p| p.x)), Sc(r.map(|p| p.y)), Sc(r.map(|p| p.z))]
    }
    #[inline(always)]
    fn rows3(c: [Sc; 3]) -> [Vec3A; GROUP] {
        std::array::from_fn(|l| Vec3A::new(c[0].0[l], c[1].0[l], c[2].0[l]))
    }
}

/// AVX lanes. Values of this type are only created inside functions compiled with
/// `#[target_feature(enable = "avx2,fma")]` (`groups_avx2` in `fused.rs`, `rotation_chunk_avx2` in
/// `rotation.rs`), which run only after `is_x86_feature_detected!` confirmed AVX2 and FMA, so
/// every intrinsic below is supported.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct Avx(pub std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
macro_rules! avx_binop {
    ($tr:ident, $f:ident, $intr:ident) => {
        impl $tr for Avx {
            type Output = Avx;
            #[inline(always)]
            fn $f(self, o: Avx) -> Avx {
                // SAFETY: AVX is present (see `Avx`); register-only operation.
                Avx(unsafe { std::arch::x86_64::$intr(self.0, o.0) })
            }
        }
    };
}
#[cfg(target_arch = "x86_64")]
avx_binop!(Add, add, _mm256_add_ps);
#[cfg(target_arch = "x86_64")]
avx_binop!(Sub, sub, _mm256_sub_ps);
#[cfg(target_arch = "x86_64")]
avx_binop!(Mul, mul, _mm256_mul_ps);
#[cfg(target_arch = "x86_64")]
avx_binop!(Div, div, _mm256_div_ps);

#[cfg(target_arch = "x86_64")]
impl Lanes for Avx {
    #[inline(always)]
    fn splat(v: f32) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_set1_ps(v) })
    }
    #[inline(always)]
    fn load(a: &[f32; GROUP]) -> Avx {
        // SAFETY: AVX is present (see `Avx`); `a` is eight readable floats (unaligned load).
        Avx(unsafe { std::arch::x86_64::_mm256_loadu_ps(a.as_ptr()) })
    }
    #[inline(always)]
    fn sqrt(self) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_sqrt_ps(self.0) })
    }
    #[inline(always)]
    fn mul_add(self, b: Avx, c: Avx) -> Avx {
        // SAFETY: AVX2 and FMA are present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_fmadd_ps(self.0, b.0, c.0) })
    }
    #[inline(always)]
    fn max(self, o: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_max_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn min(self, o: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_min_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn le(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn eq(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn gt(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn ne(self, o: Avx) -> Avx {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { _mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, o.0) })
    }
    #[inline(always)]
    fn and(self, o: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_and_ps(self.0, o.0) })
    }
    #[inline(always)]
    fn select(m: Avx, a: Avx, b: Avx) -> Avx {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        Avx(unsafe { std::arch::x86_64::_mm256_blendv_ps(b.0, a.0, m.0) })
    }
    #[inline(always)]
    fn bits(self) -> u32 {
        // SAFETY: AVX is present (see `Avx`); register-only operation.
        unsafe { std::arch::x86_64::_mm256_movemask_ps(self.0) as u32 }
    }
    #[inline(always)]
    fn rot_min(vl: Avx, fa: Avx, m: Avx, sl: Avx, theta: f64, best: &mut f64) {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operations, plus one store into a
        // local array of four doubles.
        unsafe {
            let (t64, two, four, zero, inf) = (
                _mm256_set1_pd(theta),
                _mm256_set1_pd(2.0),
                _mm256_set1_pd(4.0),
                _mm256_setzero_pd(),
                _mm256_set1_pd(f64::INFINITY),
            );
            let lo = |q: Avx| _mm256_cvtps_pd(_mm256_castps256_ps128(q.0));
            let hi = |q: Avx| _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(q.0));
            let mut acc = inf;
            for (v, f, mm, s) in [(lo(vl), lo(fa), lo(m), lo(sl)), (hi(vl), hi(fa), hi(m), hi(sl))] {
                let reach = _mm256_mul_pd(t64, s);
                let a = _mm256_div_pd(f, mm);
                let root =
                    _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(v, v), _mm256_mul_pd(_mm256_mul_pd(four, a), reach)));
                let h1 = _mm256_div_pd(_mm256_mul_pd(two, reach), _mm256_add_pd(v, root));
                let h2 = _mm256_blendv_pd(inf, _mm256_div_pd(reach, v), _mm256_cmp_pd::<_CMP_GT_OQ>(v, zero));
                let h = _mm256_blendv_pd(h2, h1, _mm256_cmp_pd::<_CMP_GT_OQ>(a, zero));
                let finite = _mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(reach, reach), zero);
                // minpd keeps the second operand when the first is NaN: NaN is ignored, as f64::min.
                acc = _mm256_min_pd(_mm256_blendv_pd(inf, h, finite), acc);
            }
            let mut lanes = [0.0f64; 4];
            _mm256_storeu_pd(lanes.as_mut_ptr(), acc);
            for q in lanes {
                *best = best.min(q);
            }
        }
    }
    #[inline(always)]
    fn gather3(src: &[Vec3A], idx: &[u32; GROUP]) -> [Avx; 3] {
        use std::arch::x86_64::*;
        let r = |l: usize| -> __m128 { src[idx[l] as usize].into() };
        let (a0, a1, a2, a3, a4, a5, a6, a7) = (r(0), r(1), r(2), r(3), r(4), r(5), r(6), r(7));
        // SAFETY: AVX is present (see `Avx`); register-only operations (a 4×4 transpose in each
        // 128-bit half: rows 0–3 low, 4–7 high).
        unsafe {
            let r0 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a0), a4);
            let r1 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a1), a5);
            let r2 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a2), a6);
            let r3 = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(a3), a7);
            let t0 = _mm256_unpacklo_ps(r0, r1);
            let t1 = _mm256_unpacklo_ps(r2, r3);
            let t2 = _mm256_unpackhi_ps(r0, r1);
            let t3 = _mm256_unpackhi_ps(r2, r3);
            [
                Avx(_mm256_shuffle_ps::<0x44>(t0, t1)),
                Avx(_mm256_shuffle_ps::<0xEE>(t0, t1)),
                Avx(_mm256_shuffle_ps::<0x44>(t2, t3)),
            ]
        }
    }
    #[inline(always)]
    fn rows3(c: [Avx; 3]) -> [Vec3A; GROUP] {
        use std::arch::x86_64::*;
        // SAFETY: AVX is present (see `Avx`); register-only operations (the inverse transpose,
        // the fourth component zero).
        unsafe {
            let z = _mm256_setzero_ps();
            let t0 = _mm256_unpacklo_ps(c[0].0, c[1].0);
            let t1 = _mm256_unpackhi_ps(c[0].0, c[1].0);
            let u0 = _mm256_unpacklo_ps(c[2].0, z);
            let u1 = _mm256_unpackhi_ps(c[2].0, z);
            let (r0, r1, r2, r3) = (
                _mm256_shuffle_ps::<0x44>(t0, u0),
                _mm256_shuffle_ps::<0xEE>(t0, u0),
                _mm256_shuffle_ps::<0x44>(t1, u1),
                _mm256_shuffle_ps::<0xEE>(t1, u1),
            );
            [
                Vec3A::from(_mm256_castps256_ps128(r0)),
                Vec3A::from(_mm256_castps256_ps128(r1)),
                Vec3A::from(_mm256_castps256_ps128(r2)),
                Vec3A::from(_mm256_castps256_ps128(r3)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r0)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r1)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r2)),
                Vec3A::from(_mm256_extractf128_ps::<1>(r3)),
            ]
        }
    }
}

/// Three component lanes.
pub(super) type V3<V> = [V; 3];

/// `[f(0), f(1), f(2)]` without a closure (closures would not inherit the kernel's target
/// features, and the intrinsics in them would not be inlined).
macro_rules! map3 {
    ($a:ident => $e:expr) => {
        [
            {
                let $a = 0;
                $e
            },
            {
                let $a = 1;
                $e
            },
            {
                let $a = 2;
                $e
            },
        ]
    };
}

/// Eight lanes of `a` from group base `base`.
#[inline(always)]
pub(super) fn at<V: Lanes>(a: &[f32], base: usize) -> V {
    V::load(a[base..base + GROUP].try_into().expect("whole groups"))
}

/// A mask of the lanes whose index is not `NONE`, and the indices with `NONE` replaced by the
/// lane's own mass.
#[inline(always)]
pub(super) fn present<V: Lanes>(idx: &[u32; GROUP], lanes: &[u32; GROUP]) -> (V, [u32; GROUP]) {
    let mut m = [0.0f32; GROUP];
    let mut o = *idx;
    for l in 0..GROUP {
        if idx[l] != NONE {
            m[l] = f32::from_bits(u32::MAX);
        } else {
            o[l] = lanes[l];
        }
    }
    (V::load(&m), o)
}

#[inline(always)]
pub(super) fn dot3<V: Lanes>(a: &V3<V>, b: &V3<V>) -> V {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(super) use map3;

/// The `h` with `v h + a h² = reach` (speed `v`, acceleration `a`, finite `reach`): one mass's
/// rotation-limited step (`rotation.rs`), here below both its users, [`Lanes::rot_min`] and
/// `rotation.rs`.
#[inline(always)]
pub(super) fn rotation_step(v: f64, a: f64, reach: f64) -> f64 {
    if !reach.is_finite() {
        f64::INFINITY
    } else if a > 0.0 {
        2.0 * reach / (v + (v * v + 4.0 * a * reach).sqrt())
    } else if v > 0.0 {
        reach / v
    } else {
        f64::INFINITY
    }
}
