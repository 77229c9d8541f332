//! The planner's random numbers: one seedable generator for every draw, and beside it four
//! streams in vector lanes that hand the uniform sampler eight fractions at a time.
//!
//! The scalar generator (xoshiro256++) gives every draw through [`rand::Rng`] exactly what it
//! gave before the lanes existed, so problem generation, inverse kinematics and the
//! experience samplers keep their streams. The uniform sampler, drawing eight joints on every
//! iteration of the search, takes its fractions from four xoshiro256+ streams stepped
//! together (AVX2 when the CPU has it, chosen at run time; the same integer arithmetic either
//! way, so every path gives the same numbers): under half the instructions of eight scalar
//! draws and their scaling. The streams start from the scalar generator's state jumped 2¹⁹² ahead, so they do
//! not overlap its own stream.

use rand::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Streams stepped together.
const STREAMS: usize = 4;

/// The planner's random number generator (see the module docs): seedable, identical on every
/// platform.
#[derive(Debug, Clone)]
pub struct PlannerRng {
    scalar: Xoshiro256PlusPlus,
    /// The streams' states, word-major: `lanes[w][k]` is word `w` of stream `k`.
    lanes: [[u64; STREAMS]; 4],
    /// Read only where the AVX2 paths are compiled (x86-64).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    avx2: bool,
}

impl PlannerRng {
    fn new(scalar: Xoshiro256PlusPlus) -> Self {
        let mut jumped = scalar.clone();
        jumped.long_jump();
        let mut lanes = [[0u64; STREAMS]; 4];
        for k in 0..STREAMS {
            // A state of all zeros would stay zero; xoshiro's output is never four zeros in a
            // row in practice, but the guard costs nothing.
            loop {
                for word in lanes.iter_mut() {
                    word[k] = jumped.next_u64();
                }
                if lanes.iter().any(|w| w[k] != 0) {
                    break;
                }
            }
        }
        PlannerRng {
            scalar,
            lanes,
            avx2: crate::collision::batch::lanes::has_avx2(),
        }
    }

    /// Fills `out` with values uniform in `[lower, lower + span)` per entry (a fraction with 52
    /// random bits, scaled), eight per two steps of the streams (the last steps' surplus
    /// dropped).
    #[inline]
    pub fn fill_uniform(&mut self, lower: &[f64], span: &[f64], out: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked at construction).
            return unsafe { self.fill_uniform_avx2(lower, span, out) };
        }
        self.fill_uniform_lanes(lower, span, out)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn fill_uniform_avx2(&mut self, lower: &[f64], span: &[f64], out: &mut [f64]) {
        self.fill_uniform_lanes(lower, span, out)
    }

    /// Two steps of the four streams per eight values: plain loops over the lanes, one vector
    /// instruction each where the target has the width.
    #[inline(always)]
    fn fill_uniform_lanes(&mut self, lower: &[f64], span: &[f64], out: &mut [f64]) {
        let n = out.len().min(lower.len()).min(span.len());
        let mut out = out[..n].chunks_exact_mut(EIGHT);
        let (mut lower, mut span) = (
            lower[..n].chunks_exact(EIGHT),
            span[..n].chunks_exact(EIGHT),
        );
        for ((o, l), s) in (&mut out).zip(&mut lower).zip(&mut span) {
            let x = self.next8();
            for k in 0..EIGHT {
                o[k] = l[k] + s[k] * fraction(x[k]);
            }
        }
        let o = out.into_remainder();
        if !o.is_empty() {
            let x = self.next8();
            for (k, ((o, l), s)) in o
                .iter_mut()
                .zip(lower.remainder())
                .zip(span.remainder())
                .enumerate()
            {
                *o = l + s * fraction(x[k]);
            }
        }
    }

    /// Eight outputs: two steps of the four streams.
    #[inline(always)]
    fn next8(&mut self) -> [u64; EIGHT] {
        let (a, b) = (step(&mut self.lanes), step(&mut self.lanes));
        std::array::from_fn(|k| if k < STREAMS { a[k] } else { b[k - STREAMS] })
    }
}

/// Values per [`PlannerRng::next8`].
const EIGHT: usize = 2 * STREAMS;

/// One xoshiro256+ step of every stream: their outputs.
// Indexed: each lane's step reads and writes the same lane of four arrays.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn step(s: &mut [[u64; STREAMS]; 4]) -> [u64; STREAMS] {
    let out = std::array::from_fn(|k| s[0][k].wrapping_add(s[3][k]));
    for k in 0..STREAMS {
        let t = s[1][k] << 17;
        s[2][k] ^= s[0][k];
        s[3][k] ^= s[1][k];
        s[1][k] ^= s[2][k];
        s[0][k] ^= s[3][k];
        s[2][k] ^= t;
        s[3][k] = s[3][k].rotate_left(45);
    }
    out
}

/// The top 52 bits of `x` as a fraction in `[0, 1)`: they fill the mantissa of a number in
/// `[1, 2)`, less one (exact, and a vector instruction each, where a conversion from a 64-bit
/// integer is not).
#[inline(always)]
fn fraction(x: u64) -> f64 {
    f64::from_bits((x >> 12) | 0x3ff0_0000_0000_0000) - 1.0
}

impl RngCore for PlannerRng {
    #[inline]
    fn next_u32(&mut self) -> u32 {
        self.scalar.next_u32()
    }

    #[inline]
    fn next_u64(&mut self) -> u64 {
        self.scalar.next_u64()
    }

    #[inline]
    fn fill_bytes(&mut self, dst: &mut [u8]) {
        self.scalar.fill_bytes(dst)
    }
}

impl SeedableRng for PlannerRng {
    type Seed = <Xoshiro256PlusPlus as SeedableRng>::Seed;

    fn from_seed(seed: Self::Seed) -> Self {
        PlannerRng::new(Xoshiro256PlusPlus::from_seed(seed))
    }

    /// As xoshiro256++'s own (SplitMix64), so a seed gives the scalar stream it always gave.
    fn seed_from_u64(state: u64) -> Self {
        PlannerRng::new(Xoshiro256PlusPlus::seed_from_u64(state))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn scalar_draws_are_xoshiro256plusplus() {
        let mut ours = PlannerRng::seed_from_u64(42);
        let mut theirs = Xoshiro256PlusPlus::seed_from_u64(42);
        let mut u = [0.0; 8];
        for _ in 0..100 {
            assert_eq!(ours.random::<u64>(), theirs.random::<u64>());
            ours.fill_uniform(&[0.0; 8], &[1.0; 8], &mut u);
            assert_eq!(ours.random::<f64>(), theirs.random::<f64>());
        }
    }

    #[test]
    fn vector_and_portable_lanes_agree_and_are_uniform() {
        let mut a = PlannerRng::seed_from_u64(7);
        let mut b = a.clone();
        b.avx2 = false;
        let mut sums = [0.0f64; 8];
        let n = 20_000;
        let (mut x, mut y) = ([0.0; 8], [0.0; 8]);
        for _ in 0..n {
            a.fill_uniform(&[0.0; 8], &[1.0; 8], &mut x);
            b.fill_uniform(&[0.0; 8], &[1.0; 8], &mut y);
            assert_eq!(x.map(f64::to_bits), y.map(f64::to_bits));
            for (s, v) in sums.iter_mut().zip(x) {
                assert!((0.0..1.0).contains(&v));
                *s += v;
            }
        }
        // Each lane's mean within five standard errors of one half (σ = 1/√12).
        let bound = 5.0 * (1.0 / 12.0f64).sqrt() / (n as f64).sqrt();
        for s in sums {
            assert!((s / n as f64 - 0.5).abs() < bound, "{}", s / n as f64);
        }
    }

    #[test]
    fn seeds_give_their_own_streams() {
        let draw = |seed| {
            let mut u = [0.0; 11];
            PlannerRng::seed_from_u64(seed).fill_uniform(&[-1.0; 11], &[3.0; 11], &mut u);
            u
        };
        assert_eq!(draw(1), draw(1));
        assert_ne!(draw(1), draw(2));
        assert!(draw(3).iter().all(|u| (-1.0..2.0).contains(u)));
    }
}
