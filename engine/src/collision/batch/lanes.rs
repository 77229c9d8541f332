//! Eight `f32` lanes and the arithmetic the batch checker needs, written as plain loops over
//! arrays: inside a function compiled for AVX2 each operation is one vector instruction, and
//! elsewhere the compiler uses what the target has (SSE2 pairs, NEON). Products added to a
//! sum are fused multiply-adds ([`F8::mul_add`]), rounded once: one instruction under AVX2
//! (whose code path needs FMA too, as every AVX2 CPU has it) and NEON, a correctly rounded
//! library call on a baseline x86-64, so every path computes the same values.

use std::ops::{Add, Mul, Sub};

/// Number of lanes: configurations checked together.
pub const LANES: usize = 8;

/// Every lane, as bits (the form lane masks take).
pub const ALL_LANES: u32 = (1 << LANES) - 1;

/// True when the CPU runs AVX2 and FMA (the code paths compiled for them are then chosen at
/// run time).
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Eight `f32` values, one per configuration.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C, align(32))]
pub struct F8(pub [f32; LANES]);

impl F8 {
    /// Every lane `v`.
    #[inline(always)]
    pub fn splat(v: f32) -> Self {
        F8([v; LANES])
    }

    #[inline(always)]
    fn map2(self, o: F8, f: impl Fn(f32, f32) -> f32) -> F8 {
        F8(std::array::from_fn(|k| f(self.0[k], o.0[k])))
    }

    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> F8 {
        F8(std::array::from_fn(|k| f(self.0[k])))
    }

    /// Lane-wise `self · a + b`, rounded once (a fused multiply-add: one instruction where the
    /// CPU has FMA, a library call elsewhere; the same value either way).
    #[inline(always)]
    pub fn mul_add(self, a: F8, b: F8) -> F8 {
        F8(std::array::from_fn(|k| self.0[k].mul_add(a.0[k], b.0[k])))
    }

    /// Lane-wise `self · a − b`, rounded once (see [`F8::mul_add`]).
    #[inline(always)]
    pub fn mul_sub(self, a: F8, b: F8) -> F8 {
        F8(std::array::from_fn(|k| self.0[k].mul_add(a.0[k], -b.0[k])))
    }

    /// Lane-wise minimum.
    #[inline(always)]
    pub fn min(self, o: F8) -> F8 {
        self.map2(o, |a, b| if a < b { a } else { b })
    }

    /// Lane-wise maximum.
    #[inline(always)]
    pub fn max(self, o: F8) -> F8 {
        self.map2(o, |a, b| if a > b { a } else { b })
    }

    /// Lane-wise absolute value.
    #[inline(always)]
    pub fn abs(self) -> F8 {
        self.map(f32::abs)
    }

    /// Lane-wise floor.
    #[inline(always)]
    pub fn floor(self) -> F8 {
        self.map(f32::floor)
    }

    /// The lanes as integers, for lanes holding whole numbers in `[0, 2²²)` (others give
    /// meaningless values): adding 1.5·2²³ puts the number in the low bits of the sum, so the
    /// conversion is two vector instructions (a saturating `as` is scalar per lane).
    #[inline(always)]
    pub fn small_uints(self) -> [u32; LANES] {
        const MAGIC: f32 = 12_582_912.0;
        self.0
            .map(|v| (v + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits()))
    }

    /// Lane-wise square root.
    #[inline(always)]
    pub fn sqrt(self) -> F8 {
        self.map(f32::sqrt)
    }

    /// True when some lane of `self` is below the same lane of `o`, for finite lanes and `o`
    /// not zero (squared distances against squared radii): the sign bits of the
    /// differences. Written as flags or-ed together, it becomes one vector test (`vtestps`)
    /// under AVX; an or of the bits across the lanes took seven instructions.
    #[inline(always)]
    pub fn any_lt(self, o: F8) -> bool {
        let d = self - o;
        // A loop, not `array::map`, as in `Mask8::any`.
        let mut any = false;
        for v in d.0 {
            any |= (v.to_bits() as i32) < 0;
        }
        any
    }

    /// The lanes where [`F8::any_lt`] finds `self` below `o` (the sign bits of the
    /// differences), as a lane mask.
    #[inline(always)]
    pub fn lt_mask(self, o: F8) -> Mask8 {
        let d = self - o;
        Mask8(std::array::from_fn(|k| {
            if (d.0[k].to_bits() as i32) < 0 {
                u32::MAX
            } else {
                0
            }
        }))
    }

    /// The lanes where `self` is at most `o`, as a lane mask (for several tests and-ed
    /// before their bits are taken out once).
    #[inline(always)]
    pub fn le(self, o: F8) -> Mask8 {
        Mask8(std::array::from_fn(|k| {
            if self.0[k] <= o.0[k] {
                u32::MAX
            } else {
                0
            }
        }))
    }

    /// Lane-wise `a` where `m` is set, else `b` (one blend under AVX).
    #[inline(always)]
    pub fn select(m: Mask8, a: F8, b: F8) -> F8 {
        F8(std::array::from_fn(|k| {
            if m.0[k] != 0 {
                a.0[k]
            } else {
                b.0[k]
            }
        }))
    }

    /// The least lane (halving, so it runs in vector halves).
    #[inline(always)]
    pub fn hmin(self) -> f32 {
        let min = |a: f32, b: f32| if a < b { a } else { b };
        let v = self.0;
        let a: [f32; 4] = std::array::from_fn(|k| min(v[k], v[k + 4]));
        min(min(a[0], a[2]), min(a[1], a[3]))
    }

    /// The greatest lane (halving).
    #[inline(always)]
    pub fn hmax(self) -> f32 {
        let max = |a: f32, b: f32| if a > b { a } else { b };
        let v = self.0;
        let a: [f32; 4] = std::array::from_fn(|k| max(v[k], v[k + 4]));
        max(max(a[0], a[2]), max(a[1], a[3]))
    }

    /// Sine and cosine of every lane, for angles of a few turns at most (joint values):
    /// reduction by π in two parts to [-π/2, π/2], then minimax polynomials there (error
    /// below 1e-7, the `f32` rounding); an odd multiple of π flips both signs.
    #[inline(always)]
    pub fn sin_cos(self) -> (F8, F8) {
        const ONE_OVER_PI: f32 = std::f32::consts::FRAC_1_PI;
        const PI_HI: f32 = std::f32::consts::PI;
        const PI_LO: f32 = -8.742_278e-8;
        // sin r = r + r³·S(r²), cos r = 1 + r²·C(r²): near-minimax on [-π/2, π/2].
        const S: [f32; 4] = [
            -0.166_666_57,
            0.008_333_017,
            -0.000_198_066_16,
            2.600_058e-6,
        ];
        const C: [f32; 4] = [-0.499_999_3, 0.041_663_99, -0.001_385_592_9, 2.319_442_5e-5];
        let mut s = [0.0; LANES];
        let mut c = [0.0; LANES];
        for k in 0..LANES {
            let x = self.0[k];
            let n = (x * ONE_OVER_PI).round_ties_even();
            let r = n.mul_add(-PI_LO, n.mul_add(-PI_HI, x));
            let r2 = r * r;
            let sp = r2.mul_add(r2.mul_add(r2.mul_add(S[3], S[2]), S[1]), S[0]);
            let sin_r = (r * r2).mul_add(sp, r);
            let cos_r = r2.mul_add(
                r2.mul_add(r2.mul_add(r2.mul_add(C[3], C[2]), C[1]), C[0]),
                1.0,
            );
            // The parity of n, read from the last mantissa bit of n + 1.5·2²³ (n's in two's
            // complement) and moved to the sign bit: flipping it is negation.
            let flip = (n + 12_582_912.0).to_bits() << 31;
            s[k] = f32::from_bits(sin_r.to_bits() ^ flip);
            c[k] = f32::from_bits(cos_r.to_bits() ^ flip);
        }
        (F8(s), F8(c))
    }
}

/// Eight lane flags (all bits set or clear), as comparisons of [`F8`] give them.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(32))]
pub struct Mask8([u32; LANES]);

impl Mask8 {
    /// Bit `k` set where lane `k` is set: the sign bits, moved out four lanes at a time.
    #[inline(always)]
    pub fn bits(self) -> u32 {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{__m128, _mm_movemask_ps};
            // SAFETY: 32 bytes of lane flags as two SSE vectors (a bit cast); SSE is part of
            // the x86-64 baseline.
            unsafe {
                let [lo, hi]: [__m128; 2] = std::mem::transmute(self.0);
                (_mm_movemask_ps(lo) | _mm_movemask_ps(hi) << 4) as u32
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            (0..LANES).fold(0, |m, k| m | (self.0[k] >> 31) << k)
        }
    }
}

impl Mask8 {
    /// The lanes whose bit is set in `bits`.
    #[inline(always)]
    pub fn from_bits(bits: u32) -> Mask8 {
        Mask8(std::array::from_fn(|k| ((bits >> k) & 1).wrapping_neg()))
    }

    /// True when some lane is set: flags or-ed together, one vector test under AVX.
    #[inline(always)]
    pub fn any(self) -> bool {
        // A loop, not `array::map`: the map's closure was once left uninlined (and so
        // compiled without AVX) in the batch checker.
        let mut any = false;
        for b in self.0 {
            any |= (b as i32) < 0;
        }
        any
    }

    /// The lanes set in `self` and not in `o`.
    #[inline(always)]
    pub fn and_not(self, o: Mask8) -> Mask8 {
        Mask8(std::array::from_fn(|k| self.0[k] & !o.0[k]))
    }
}

impl std::ops::BitAnd for Mask8 {
    type Output = Mask8;
    #[inline(always)]
    fn bitand(self, o: Mask8) -> Mask8 {
        Mask8(std::array::from_fn(|k| self.0[k] & o.0[k]))
    }
}

impl Add for F8 {
    type Output = F8;
    #[inline(always)]
    fn add(self, o: F8) -> F8 {
        self.map2(o, |a, b| a + b)
    }
}

impl Sub for F8 {
    type Output = F8;
    #[inline(always)]
    fn sub(self, o: F8) -> F8 {
        self.map2(o, |a, b| a - b)
    }
}

impl Mul for F8 {
    type Output = F8;
    #[inline(always)]
    fn mul(self, o: F8) -> F8 {
        self.map2(o, |a, b| a * b)
    }
}

/// A rigid transform per lane: rotation `r` (row-major) and translation `t`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Pose8 {
    /// Rotation, row-major.
    pub r: [F8; 9],
    /// Translation.
    pub t: [F8; 3],
}

impl Pose8 {
    /// The same transform in every lane (row-major rotation, translation).
    pub fn splat(r: [f32; 9], t: [f32; 3]) -> Self {
        Pose8 {
            r: r.map(F8::splat),
            t: t.map(F8::splat),
        }
    }

    /// The rotation `a · self.r` (`a` row-major).
    #[inline(always)]
    pub fn r_after(&self, a: &[F8; 9]) -> [F8; 9] {
        // Written out: `array::from_fn` left its closure apart from the caller's AVX2.
        let b = &self.r;
        [
            dot3(a, b, 0, 0),
            dot3(a, b, 0, 1),
            dot3(a, b, 0, 2),
            dot3(a, b, 1, 0),
            dot3(a, b, 1, 1),
            dot3(a, b, 1, 2),
            dot3(a, b, 2, 0),
            dot3(a, b, 2, 1),
            dot3(a, b, 2, 2),
        ]
    }

    /// The image of lane points `p`.
    #[inline(always)]
    pub fn apply(&self, p: [F8; 3]) -> [F8; 3] {
        let a = &self.r;
        [
            a[0].mul_add(p[0], a[1].mul_add(p[1], a[2].mul_add(p[2], self.t[0]))),
            a[3].mul_add(p[0], a[4].mul_add(p[1], a[5].mul_add(p[2], self.t[1]))),
            a[6].mul_add(p[0], a[7].mul_add(p[1], a[8].mul_add(p[2], self.t[2]))),
        ]
    }

    /// Lane points `p` in this frame: the inverse transform, `rᵀ (p − t)`.
    #[inline(always)]
    pub fn apply_inverse(&self, p: [F8; 3]) -> [F8; 3] {
        let a = &self.r;
        let d = [p[0] - self.t[0], p[1] - self.t[1], p[2] - self.t[2]];
        [
            a[0].mul_add(d[0], a[3].mul_add(d[1], a[6] * d[2])),
            a[1].mul_add(d[0], a[4].mul_add(d[1], a[7] * d[2])),
            a[2].mul_add(d[0], a[5].mul_add(d[1], a[8] * d[2])),
        ]
    }

    /// [`Pose8::apply_const`], in AVX2 registers when `avx2` (the CPU has it: the caller
    /// checked). The same operations in the same order; written out because LLVM, vectorising
    /// the lane arrays itself, at some call sites paired the rows' lanes and gathered the
    /// rotation's entries one by one (three times the instructions).
    #[inline(always)]
    pub fn apply_const_on(&self, c: [f32; 3], avx2: bool) -> [F8; 3] {
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the CPU has AVX2 (the caller says so, from `has_avx2`).
            return unsafe { self.apply_const_avx2(c) };
        }
        let _ = avx2;
        self.apply_const(c)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    unsafe fn apply_const_avx2(&self, c: [f32; 3]) -> [F8; 3] {
        use std::arch::x86_64::*;
        let (x, y, z) = (
            _mm256_set1_ps(c[0]),
            _mm256_set1_ps(c[1]),
            _mm256_set1_ps(c[2]),
        );
        let mut out = [F8::default(); 3];
        for (i, o) in out.iter_mut().enumerate() {
            // SAFETY: an `F8` is 32 bytes aligned to 32. (No closure: it would be compiled
            // without this function's AVX2.)
            let (a0, a1, a2, t) = unsafe {
                (
                    _mm256_load_ps(self.r[3 * i].0.as_ptr()),
                    _mm256_load_ps(self.r[3 * i + 1].0.as_ptr()),
                    _mm256_load_ps(self.r[3 * i + 2].0.as_ptr()),
                    _mm256_load_ps(self.t[i].0.as_ptr()),
                )
            };
            let v = _mm256_fmadd_ps(a0, x, _mm256_fmadd_ps(a1, y, _mm256_fmadd_ps(a2, z, t)));
            // SAFETY: as above.
            unsafe { _mm256_store_ps(o.0.as_mut_ptr(), v) };
        }
        out
    }

    /// The image of the fixed point `c` (the same in every lane).
    #[inline(always)]
    pub fn apply_const(&self, c: [f32; 3]) -> [F8; 3] {
        let a = &self.r;
        let (x, y, z) = (F8::splat(c[0]), F8::splat(c[1]), F8::splat(c[2]));
        [
            a[0].mul_add(x, a[1].mul_add(y, a[2].mul_add(z, self.t[0]))),
            a[3].mul_add(x, a[4].mul_add(y, a[5].mul_add(z, self.t[1]))),
            a[6].mul_add(x, a[7].mul_add(y, a[8].mul_add(z, self.t[2]))),
        ]
    }
}

/// The fractions `ks[i] / n` along an edge of `n` steps (every `ks[i]` at most `n`), in
/// `f64`: eight divisions in two AVX2 instructions when `avx2` (the caller checked the CPU)
/// and `n` fits an `i32`, the same correctly rounded quotients either way.
#[inline(always)]
pub fn edge_fractions(ks: &[usize; LANES], n: usize, avx2: bool) -> [f64; LANES] {
    #[cfg(target_arch = "x86_64")]
    if avx2 && n <= i32::MAX as usize {
        debug_assert!(ks.iter().all(|&k| k <= n));
        // SAFETY: the CPU has AVX2 (the caller says so, from `has_avx2`).
        return unsafe { edge_fractions_avx2(ks, n) };
    }
    let _ = avx2;
    std::array::from_fn(|i| ks[i] as f64 / n as f64)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn edge_fractions_avx2(ks: &[usize; LANES], n: usize) -> [f64; LANES] {
    use std::arch::x86_64::*;
    let k: [i32; LANES] = std::array::from_fn(|i| ks[i] as i32);
    // SAFETY: `k` holds eight values (unaligned loads and stores).
    unsafe {
        let n = _mm256_set1_pd(n as f64);
        let lo = _mm256_cvtepi32_pd(_mm_loadu_si128(k.as_ptr().cast()));
        let hi = _mm256_cvtepi32_pd(_mm_loadu_si128(k.as_ptr().add(4).cast()));
        let mut out = [0.0; LANES];
        _mm256_storeu_pd(out.as_mut_ptr(), _mm256_div_pd(lo, n));
        _mm256_storeu_pd(out.as_mut_ptr().add(4), _mm256_div_pd(hi, n));
        out
    }
}

/// Writes the eight points `start + t[i] · delta` of an edge into `out`, variable by variable
/// (`out[j]` lane `i` = `start[j] + t[i] · delta[j]`, in `f64`, then rounded), in AVX2
/// registers when `avx2` (the caller checked the CPU). The same operations either way: LLVM
/// left the portable loop's conversions lane by lane.
#[inline(always)]
pub fn edge_lanes(out: &mut [F8], start: &[f64], delta: &[f64], t: &[f64; LANES], avx2: bool) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: the CPU has AVX2 (the caller says so, from `has_avx2`).
        return unsafe { edge_lanes_avx2(out, start, delta, t) };
    }
    let _ = avx2;
    for ((lane, &a), &d) in out.iter_mut().zip(start).zip(delta) {
        *lane = F8(std::array::from_fn(|i| (a + t[i] * d) as f32));
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn edge_lanes_avx2(out: &mut [F8], start: &[f64], delta: &[f64], t: &[f64; LANES]) {
    use std::arch::x86_64::*;
    // SAFETY: `t` holds eight values (unaligned loads).
    let (t_lo, t_hi) = unsafe {
        (
            _mm256_loadu_pd(t.as_ptr()),
            _mm256_loadu_pd(t.as_ptr().add(4)),
        )
    };
    for ((lane, &a), &d) in out.iter_mut().zip(start).zip(delta) {
        let (a, d) = (_mm256_set1_pd(a), _mm256_set1_pd(d));
        let lo = _mm256_cvtpd_ps(_mm256_add_pd(a, _mm256_mul_pd(t_lo, d)));
        let hi = _mm256_cvtpd_ps(_mm256_add_pd(a, _mm256_mul_pd(t_hi, d)));
        // SAFETY: an `F8` is 32 bytes aligned to 32.
        unsafe { _mm256_store_ps(lane.0.as_mut_ptr(), _mm256_set_m128(hi, lo)) };
    }
}

/// The lanes (as bits) whose box `[lo, hi]` (per axis, eight boxes in lanes) overlaps the
/// box `[b_lo, b_hi]` (the same in every lane), in AVX2 registers when `avx2` (the caller
/// checked the CPU). Comparisons only, so the same answer either way; LLVM computed the
/// portable form in halves.
#[inline(always)]
pub fn boxes_overlapping(
    lo: &[F8; 3],
    hi: &[F8; 3],
    b_lo: [f32; 3],
    b_hi: [f32; 3],
    avx2: bool,
) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: the CPU has AVX2 (the caller says so, from `has_avx2`).
        return unsafe { boxes_overlapping_avx2(lo, hi, b_lo, b_hi) };
    }
    let _ = avx2;
    let reach = (lo[0].le(F8::splat(b_hi[0])) & F8::splat(b_lo[0]).le(hi[0]))
        & (lo[1].le(F8::splat(b_hi[1])) & F8::splat(b_lo[1]).le(hi[1]))
        & (lo[2].le(F8::splat(b_hi[2])) & F8::splat(b_lo[2]).le(hi[2]));
    reach.bits()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn boxes_overlapping_avx2(
    lo: &[F8; 3],
    hi: &[F8; 3],
    b_lo: [f32; 3],
    b_hi: [f32; 3],
) -> u32 {
    use std::arch::x86_64::*;
    let mut reach = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    for a in 0..3 {
        // SAFETY: an `F8` is 32 bytes aligned to 32.
        let (l, h) = unsafe {
            (
                _mm256_load_ps(lo[a].0.as_ptr()),
                _mm256_load_ps(hi[a].0.as_ptr()),
            )
        };
        let below = _mm256_cmp_ps::<_CMP_LE_OQ>(l, _mm256_set1_ps(b_hi[a]));
        let above = _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_set1_ps(b_lo[a]), h);
        reach = _mm256_and_ps(reach, _mm256_and_ps(below, above));
    }
    _mm256_movemask_ps(reach) as u32
}

/// Entry `(i, j)` of the product `a · b` of row-major rotations.
#[inline(always)]
fn dot3(a: &[F8; 9], b: &[F8; 9], i: usize, j: usize) -> F8 {
    a[i * 3].mul_add(
        b[j],
        a[i * 3 + 1].mul_add(b[3 + j], a[i * 3 + 2] * b[6 + j]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Repeatable test values in `[-half_width, half_width)` (a 64-bit linear congruential
    /// sequence from `seed`).
    fn values(mut seed: u64, half_width: f64) -> impl FnMut() -> f64 {
        move || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * half_width
        }
    }

    /// The AVX2 placement of a fixed point gives the portable one's values, bit for bit, on
    /// poses with a different rotation and translation in every lane.
    #[test]
    fn placement_in_avx2_equals_the_portable_one() {
        if !has_avx2() {
            return;
        }
        let mut values = values(7, 2.0);
        let mut next = || values() as f32;
        for _ in 0..200 {
            let pose = Pose8 {
                r: std::array::from_fn(|_| F8(std::array::from_fn(|_| next()))),
                t: std::array::from_fn(|_| F8(std::array::from_fn(|_| next()))),
            };
            let c = [next(), next(), next()];
            let portable = pose.apply_const(c);
            let vector = pose.apply_const_on(c, true);
            for (p, v) in portable.iter().zip(&vector) {
                assert_eq!(p.0.map(f32::to_bits), v.0.map(f32::to_bits));
            }
            assert_eq!(
                pose.apply_const_on(c, false).map(|v| v.0),
                portable.map(|v| v.0)
            );
        }
    }

    /// The edge's lanes written in AVX2 equal the portable ones, bit for bit.
    #[test]
    fn edge_fractions_in_avx2_equal_the_portable_ones() {
        if !has_avx2() {
            return;
        }
        for n in [1usize, 2, 3, 7, 31, 32, 33, 97, 1000, 65_537] {
            for first in [0, 1, n / 3, n.saturating_sub(7)] {
                let ks: [usize; LANES] = std::array::from_fn(|i| (first + 5 * i) % (n + 1));
                let (p, v) = (edge_fractions(&ks, n, false), edge_fractions(&ks, n, true));
                assert_eq!(p.map(f64::to_bits), v.map(f64::to_bits), "n {n}, ks {ks:?}");
            }
        }
    }

    #[test]
    fn edge_lanes_in_avx2_equal_the_portable_ones() {
        if !has_avx2() {
            return;
        }
        let mut next = values(11, 4.0);
        for n in 1..60usize {
            let start: Vec<f64> = (0..7).map(|_| next()).collect();
            let delta: Vec<f64> = (0..7).map(|_| next()).collect();
            let t: [f64; LANES] = std::array::from_fn(|i| ((i * 5) % (n + 1)) as f64 / n as f64);
            let (mut portable, mut vector) = (vec![F8::default(); 7], vec![F8::default(); 7]);
            edge_lanes(&mut portable, &start, &delta, &t, false);
            edge_lanes(&mut vector, &start, &delta, &t, true);
            for (j, (p, v)) in portable.iter().zip(&vector).enumerate() {
                assert_eq!(
                    p.0.map(f32::to_bits),
                    v.0.map(f32::to_bits),
                    "n {n}, joint {j}"
                );
                for (i, &x) in p.0.iter().enumerate() {
                    assert_eq!(x, (start[j] + t[i] * delta[j]) as f32);
                }
            }
        }
    }

    /// The box overlap test in AVX2 gives the portable answer and each lane's meaning.
    #[test]
    fn box_overlaps_in_avx2_equal_the_portable_ones() {
        let mut values = values(5, 1.0);
        let mut next = || values() as f32;
        for _ in 0..500 {
            let lo: [F8; 3] = std::array::from_fn(|_| F8(std::array::from_fn(|_| next())));
            let hi: [F8; 3] = std::array::from_fn(|a| F8(lo[a].0.map(|v| v + 0.3)));
            let b_lo = [next(), next(), next()];
            let b_hi = b_lo.map(|v| v + 0.2);
            let portable = boxes_overlapping(&lo, &hi, b_lo, b_hi, false);
            let meaning = (0..LANES).fold(0, |m, k| {
                let hit = (0..3).all(|a| lo[a].0[k] <= b_hi[a] && b_lo[a] <= hi[a].0[k]);
                m | (hit as u32) << k
            });
            assert_eq!(portable, meaning);
            if has_avx2() {
                assert_eq!(boxes_overlapping(&lo, &hi, b_lo, b_hi, true), portable);
            }
        }
    }

    /// The lane tests against their one-lane meaning, on values and their neighbours.
    #[test]
    fn lane_tests_match_each_lane() {
        let values = [-2.0f32, -0.5, -1e-30, 0.0, 1e-30, 0.25, 0.5, 3.0];
        for i in 0..64u32 {
            let a = F8(std::array::from_fn(|k| values[(k + i as usize) % 8]));
            let b = F8(std::array::from_fn(|k| {
                values[(k * 3 + (i / 8) as usize) % 8] + 1e-3
            }));
            let le = (0..LANES).fold(0, |m, k| m | u32::from(a.0[k] <= b.0[k]) << k);
            assert_eq!(a.le(b).bits(), le);
            let ge = (0..LANES).fold(0, |m, k| m | u32::from(b.0[k] <= a.0[k]) << k);
            assert_eq!((a.le(b) & b.le(a)).bits(), le & ge);
            assert_eq!(a.any_lt(b), (0..LANES).any(|k| a.0[k] < b.0[k]));
            let one = F8(std::array::from_fn(|k| {
                if k == (i % 8) as usize {
                    0.0
                } else {
                    5.0
                }
            }));
            assert!(one.any_lt(F8::splat(1.0)));
            assert!(!one.any_lt(F8::splat(-1.0)));
        }
    }

    #[test]
    fn sin_cos_matches_std_over_joint_ranges() {
        let mut worst = 0.0f32;
        for i in 0..20_000 {
            let x0 = -7.0 + 14.0 * i as f32 / 20_000.0;
            let (s, c) = F8(std::array::from_fn(|k| x0 + k as f32 * 1e-4)).sin_cos();
            for k in 0..LANES {
                let x = x0 as f64 + k as f64 * 1e-4;
                let x = x as f32 as f64;
                worst = worst
                    .max((s.0[k] as f64 - x.sin()).abs() as f32)
                    .max((c.0[k] as f64 - x.cos()).abs() as f32);
            }
        }
        assert!(worst < 5e-7, "worst error {worst}");
    }
}
