//! The planning group's configuration space: limits, wrapping of continuous joints, distances
//! and interpolation.
//!
//! The metric is Euclidean over joint differences, where a continuous joint's difference is the
//! shortest signed angle. Radians and metres are mixed as they are in MoveIt and OMPL.

use super::Robot;
use crate::planning::PlannerRng;
use rand::Rng;
use std::f64::consts::PI;
use thiserror::Error;

/// A configuration that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConfigError {
    /// The configuration has the wrong number of values.
    #[error("configuration has {got} values, the planning group has {expected} joints")]
    WrongLength {
        /// Degrees of freedom of the group.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A value is NaN or infinite.
    #[error("joint {joint} (index {index}) is not a finite number")]
    NotFinite {
        /// Joint name.
        joint: String,
        /// Index in the configuration.
        index: usize,
    },
    /// A value is outside the joint's limits.
    #[error("joint {joint} is {value}, outside its limits [{lower}, {upper}]")]
    OutOfLimits {
        /// Joint name.
        joint: String,
        /// The value given.
        value: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
}

/// Slack allowed on limits when validating configurations that went through text formats
/// (MotionBenchMaker goals at π against URDF limits written as ±3.14159 differ by 2.6e-6).
pub const LIMIT_TOLERANCE: f64 = 1e-5;

/// Wraps an angle into `[-π, π)`.
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    // At most one turn off is the common case (the difference of two wrapped angles is off
    // by one a quarter of the time, at random): chosen without a branch to mispredict.
    let turn = if a >= PI {
        -2.0 * PI
    } else if a < -PI {
        2.0 * PI
    } else {
        0.0
    };
    let w = a + turn;
    if (-PI..PI).contains(&w) {
        w
    } else {
        wrap_far(a)
    }
}

/// `b - a`, the shortest way round on a continuous joint.
#[inline(always)]
fn delta(continuous: bool, a: f64, b: f64) -> f64 {
    if continuous {
        wrap_angle(b - a)
    } else {
        b - a
    }
}

/// The value a fraction `t` of the way from `a` to `b`, the short way round (and wrapped) on a
/// continuous joint, and the step taken from `a` (unwrapped).
#[inline(always)]
fn stepped(continuous: bool, a: f64, b: f64, t: f64) -> (f64, f64) {
    let s = t * delta(continuous, a, b);
    (wrapped(continuous, a + s), s)
}

/// `v` wrapped on a continuous joint.
#[inline(always)]
fn wrapped(continuous: bool, v: f64) -> f64 {
    if continuous {
        wrap_angle(v)
    } else {
        v
    }
}

/// [`wrap_angle`] of an angle more than a turn outside `[-π, π)` (or not finite).
#[cold]
#[inline(never)]
fn wrap_far(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w >= PI {
        w - 2.0 * PI
    } else {
        w
    }
}

impl Robot {
    /// Checks length, finiteness and limits (continuous joints accept any finite value).
    ///
    /// ```
    /// let fetch = ember_engine::robot::Robot::builtin("fetch").unwrap();
    /// assert!(fetch.validate(fetch.named_state("stow").unwrap()).is_ok());
    /// assert!(fetch.validate(&[0.0; 3]).is_err());
    /// ```
    pub fn validate(&self, q: &[f64]) -> Result<(), ConfigError> {
        if q.len() != self.dof() {
            return Err(ConfigError::WrongLength {
                expected: self.dof(),
                got: q.len(),
            });
        }
        for (index, (v, var)) in q.iter().zip(&self.variables).enumerate() {
            if !v.is_finite() {
                return Err(ConfigError::NotFinite {
                    joint: var.name.clone(),
                    index,
                });
            }
            if !var.continuous
                && (*v < var.lower - LIMIT_TOLERANCE || *v > var.upper + LIMIT_TOLERANCE)
            {
                return Err(ConfigError::OutOfLimits {
                    joint: var.name.clone(),
                    value: *v,
                    lower: var.lower,
                    upper: var.upper,
                });
            }
        }
        Ok(())
    }

    /// Brings `q` into the canonical range: continuous joints wrapped to `[-π, π)`, others
    /// clamped to their limits.
    pub fn enforce_bounds(&self, q: &mut [f64]) {
        for (v, var) in q.iter_mut().zip(&self.variables) {
            *v = if var.continuous {
                wrap_angle(*v)
            } else {
                v.clamp(var.lower, var.upper)
            };
        }
    }

    /// Per-joint difference `b - a`, the shortest way round for continuous joints.
    #[inline]
    pub fn joint_delta(&self, i: usize, a: f64, b: f64) -> f64 {
        delta(self.variables[i].continuous, a, b)
    }

    /// Distance between two configurations (Euclidean over joint deltas).
    ///
    /// ```
    /// use std::f64::consts::PI;
    /// let fetch = ember_engine::robot::Robot::builtin("fetch").unwrap();
    /// let a = [0.0; 8];
    /// let mut b = [0.0; 8];
    /// b[3] = 2.0 * PI - 0.1; // upperarm_roll is continuous: the short way is 0.1
    /// assert!((fetch.distance(&a, &b) - 0.1).abs() < 1e-9);
    /// ```
    #[inline]
    pub fn distance(&self, a: &[f64], b: &[f64]) -> f64 {
        self.fold_deltas(a, b, |_, _| {})
    }

    /// Writes the per-joint differences from `a` to `b` ([`Robot::joint_delta`]) into `out`
    /// and returns their [`Robot::distance`], in one pass.
    #[inline]
    pub fn deltas(&self, a: &[f64], b: &[f64], out: &mut [f64]) -> f64 {
        let out = &mut out[..a.len()];
        self.fold_deltas(a, b, |i, d| out[i] = d)
    }

    /// The distance from `a` to `b`, each joint's difference handed to `each` on the way.
    #[inline(always)]
    fn fold_deltas(&self, a: &[f64], b: &[f64], mut each: impl FnMut(usize, f64)) -> f64 {
        // Sliced once (a short `b` panics, as indexing did): no bounds check per joint.
        let n = a.len();
        let (b, vars) = (&b[..n], &self.variables[..n]);
        let mut s = 0.0;
        for i in 0..n {
            let d = delta(vars[i].continuous, a[i], b[i]);
            each(i, d);
            s += d * d;
        }
        s.sqrt()
    }

    /// The configuration in the middle of every joint's limits.
    pub fn middle(&self) -> Vec<f64> {
        self.variables
            .iter()
            .map(|v| (v.lower + v.upper) / 2.0)
            .collect()
    }

    /// Writes the configuration a fraction `t` of the way from `a` to `b` into `out`.
    #[inline]
    pub fn interpolate(&self, a: &[f64], b: &[f64], t: f64, out: &mut [f64]) {
        self.interpolate_stepping::<false>(a, b, t, out, &mut []);
    }

    /// [`Robot::interpolate`], also writing the step from `a` per joint into `step`: `t` times
    /// the joint's difference ([`Robot::joint_delta`]), the value `out` adds to `a` before
    /// wrapping (so `a + step` is `out`, but for whole turns on continuous joints).
    #[inline]
    pub fn step_towards(&self, a: &[f64], b: &[f64], t: f64, out: &mut [f64], step: &mut [f64]) {
        self.interpolate_stepping::<true>(a, b, t, out, step);
    }

    #[inline(always)]
    fn interpolate_stepping<const STEP: bool>(
        &self,
        a: &[f64],
        b: &[f64],
        t: f64,
        out: &mut [f64],
        step: &mut [f64],
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.limit_box.avx2 {
            // SAFETY: the CPU has AVX2 (checked when the robot was built).
            if unsafe { self.interpolate_avx2::<STEP>(a, b, t, out, step) } {
                return;
            }
        }
        self.interpolate_scalar::<STEP>(a, b, t, out, step)
    }

    /// [`Robot::interpolate`] four joints per vector instruction, with the same arithmetic;
    /// false (and `out` partly written) when an angle is more than a turn out and needs the
    /// scalar path.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn interpolate_avx2<const STEP: bool>(
        &self,
        a: &[f64],
        b: &[f64],
        t: f64,
        out: &mut [f64],
        step: &mut [f64],
    ) -> bool {
        use std::arch::x86_64::*;
        let n = a.len();
        let (b, out, wraps) = (&b[..n], &mut out[..n], &self.limit_box.wraps[..n]);
        let step = if STEP { &mut step[..n] } else { step };
        let four = n / 4 * 4;
        let tt = _mm256_set1_pd(t);
        let mut bad = 0;
        for j in (0..four).step_by(4) {
            // SAFETY: j + 4 <= n, within every slice.
            let (va, vb) = (
                _mm256_loadu_pd(a.as_ptr().add(j)),
                _mm256_loadu_pd(b.as_ptr().add(j)),
            );
            let m = _mm256_castsi256_pd(_mm256_loadu_si256(wraps.as_ptr().add(j).cast()));
            let (d, outside_d) = wrap_where_avx2(_mm256_sub_pd(vb, va), m);
            let s = _mm256_mul_pd(tt, d);
            let (v, outside_v) = wrap_where_avx2(_mm256_add_pd(va, s), m);
            bad |= outside_d | outside_v;
            _mm256_storeu_pd(out.as_mut_ptr().add(j), v);
            if STEP {
                _mm256_storeu_pd(step.as_mut_ptr().add(j), s);
            }
        }
        for i in four..n {
            let (v, s) = stepped(wraps[i] != 0, a[i], b[i], t);
            out[i] = v;
            if STEP {
                step[i] = s;
            }
        }
        bad == 0
    }

    #[inline(always)]
    fn interpolate_scalar<const STEP: bool>(
        &self,
        a: &[f64],
        b: &[f64],
        t: f64,
        out: &mut [f64],
        step: &mut [f64],
    ) {
        let n = a.len();
        let (b, out, vars) = (&b[..n], &mut out[..n], &self.variables[..n]);
        for i in 0..n {
            let (v, s) = stepped(vars[i].continuous, a[i], b[i], t);
            out[i] = v;
            if STEP {
                step[i] = s;
            }
        }
    }

    /// Draws a configuration uniformly within the limits into `out`.
    #[inline]
    pub fn sample_uniform<R: Rng + ?Sized>(&self, rng: &mut R, out: &mut [f64]) {
        for (v, var) in out.iter_mut().zip(&self.variables) {
            // A 53-bit fraction scaled into the limits: a third of `random_range`'s work (the
            // experience samplers draw this way often). Rounding may give the upper limit.
            let u: f64 = rng.random();
            *v = var.lower + (var.upper - var.lower) * u;
        }
    }

    /// [`Robot::sample_uniform`] from the planner's generator, eight joints at a time in vector
    /// lanes ([`PlannerRng::fill_uniform`]): the search's uniform sampler.
    #[inline]
    pub fn sample_uniform_fast(&self, rng: &mut PlannerRng, out: &mut [f64]) {
        rng.fill_uniform(&self.limit_box.lower, &self.limit_box.span, out);
    }

    /// The planning group's positions picked by joint name out of a joint state that names any
    /// set of robot joints (as ROS joint states do). `Err` names the first group joint missing.
    pub fn group_positions<S: AsRef<str>>(
        &self,
        names: &[S],
        positions: &[f64],
    ) -> Result<Vec<f64>, String> {
        self.variables
            .iter()
            .map(|v| {
                names
                    .iter()
                    .position(|n| n.as_ref() == v.name)
                    .and_then(|i| positions.get(i).copied())
                    .ok_or_else(|| v.name.clone())
            })
            .collect()
    }

    /// Sum of joint ranges (continuous joints count 2π): OMPL's maximum extent.
    pub fn extent(&self) -> f64 {
        self.variables.iter().map(|v| v.upper - v.lower).sum()
    }
}

/// The joint limits, and which joints wrap, as flat arrays for the vector paths (the uniform
/// sampler, interpolation).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct LimitBox {
    /// Per variable: its lower limit.
    pub lower: Vec<f64>,
    /// Per variable: upper less lower limit.
    pub span: Vec<f64>,
    /// Per variable: all bits set on a continuous joint, else none (a lane mask).
    pub wraps: Vec<u64>,
    /// True when the CPU runs AVX2 (the vector paths are then taken).
    pub avx2: bool,
}

impl LimitBox {
    /// The box of `variables`.
    pub fn of(variables: &[super::Variable]) -> Self {
        LimitBox {
            lower: variables.iter().map(|v| v.lower).collect(),
            span: variables.iter().map(|v| v.upper - v.lower).collect(),
            wraps: variables
                .iter()
                .map(|v| if v.continuous { u64::MAX } else { 0 })
                .collect(),
            avx2: crate::collision::batch::lanes::has_avx2(),
        }
    }
}

/// [`wrap_angle`]'s arithmetic in the lanes of `x` whose mask `wraps` is set (the others
/// kept), and the bits of those lanes it did not bring within `[-π, π)` (they need the scalar
/// path).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn wrap_where_avx2(
    x: std::arch::x86_64::__m256d,
    wraps: std::arch::x86_64::__m256d,
) -> (std::arch::x86_64::__m256d, i32) {
    use std::arch::x86_64::*;
    let (pi, minus_pi) = (_mm256_set1_pd(PI), _mm256_set1_pd(-PI));
    // The turn as `wrap_angle` chooses it: −2π at or above π, 2π below −π, else none.
    let up = _mm256_cmp_pd::<_CMP_LT_OQ>(x, minus_pi);
    let down = _mm256_cmp_pd::<_CMP_GE_OQ>(x, pi);
    let turn = _mm256_blendv_pd(_mm256_setzero_pd(), _mm256_set1_pd(2.0 * PI), up);
    let turn = _mm256_blendv_pd(turn, _mm256_set1_pd(-2.0 * PI), down);
    let w = _mm256_add_pd(x, turn);
    let inside = _mm256_and_pd(
        _mm256_cmp_pd::<_CMP_GE_OQ>(w, minus_pi),
        _mm256_cmp_pd::<_CMP_LT_OQ>(w, pi),
    );
    let outside = _mm256_movemask_pd(_mm256_andnot_pd(inside, wraps));
    (_mm256_blendv_pd(x, w, wraps), outside)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_maps_into_half_open_range() {
        for a in [
            -7.0,
            -4.0,
            -PI,
            -1.0,
            0.0,
            1.0,
            PI,
            4.0,
            7.0,
            9.42,
            100.0,
            -1e9,
            6.283185307179585,
        ] {
            let sut = wrap_angle(a);
            assert!((-PI..PI).contains(&sut), "{a} -> {sut}");
            assert!(
                ((sut - a) / (2.0 * PI)).fract().abs() < 1e-9
                    || ((sut - a) / (2.0 * PI)).fract().abs() > 1.0 - 1e-9
            );
        }
        // One turn off: exactly one subtraction or addition of 2π.
        for a in [PI, 4.0, 6.0, -4.0, -PI - 1e-12, -6.0] {
            let one_turn = if a >= PI { a - 2.0 * PI } else { a + 2.0 * PI };
            assert_eq!(wrap_angle(a), one_turn, "{a}");
        }
        assert!(wrap_angle(f64::NAN).is_nan());
    }

    #[test]
    fn validate_names_the_bad_joint() {
        let sut = Robot::builtin("fetch").unwrap();
        let mut q = sut.named_state("stow").unwrap().to_vec();
        q[4] = 3.0;
        let err = sut.validate(&q).unwrap_err();
        assert!(
            matches!(err, ConfigError::OutOfLimits { ref joint, .. } if joint == "elbow_flex_joint")
        );
        q[4] = f64::NAN;
        assert!(matches!(
            sut.validate(&q),
            Err(ConfigError::NotFinite { index: 4, .. })
        ));
    }

    #[test]
    fn vector_interpolation_equals_the_scalar_path_bit_for_bit() {
        use rand::SeedableRng;
        // Fetch (eight joints: two vectors) and the Panda (seven: a vector and three).
        for name in ["fetch", "panda"] {
            let sut = Robot::builtin(name).unwrap();
            let mut rng = rand::rngs::StdRng::seed_from_u64(3);
            let n = sut.dof();
            let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
            let (mut fast, mut scalar) = (vec![0.0; n], vec![0.0; n]);
            let (mut stepped, mut step, mut scalar_step) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            let bits = |v: &[f64]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            for round in 0..20_000 {
                // Mostly within the limits, sometimes a few turns out (the scalar fallback).
                let far = if round % 10 == 0 { 12.0 } else { 0.0 };
                for q in [&mut a, &mut b] {
                    sut.sample_uniform(&mut rng, q);
                    for v in q.iter_mut() {
                        *v += far * (rng.random::<f64>() - 0.5);
                    }
                }
                let t = rng.random::<f64>();
                sut.interpolate(&a, &b, t, &mut fast);
                sut.interpolate_scalar::<false>(&a, &b, t, &mut scalar, &mut []);
                assert_eq!(bits(&fast), bits(&scalar), "{name}: {a:?} -> {b:?} at {t}");
                // The stepping form writes the same configuration, and the same step on
                // either path: `t` times the joint's difference, which `a` plus it wraps to.
                sut.step_towards(&a, &b, t, &mut stepped, &mut step);
                sut.interpolate_scalar::<true>(&a, &b, t, &mut scalar, &mut scalar_step);
                assert_eq!(bits(&stepped), bits(&fast), "{name}: {a:?} -> {b:?} at {t}");
                assert_eq!(
                    bits(&step),
                    bits(&scalar_step),
                    "{name}: {a:?} -> {b:?} at {t}"
                );
                for j in 0..n {
                    assert_eq!(step[j], t * sut.joint_delta(j, a[j], b[j]));
                }
            }
            a[3] = f64::NAN;
            sut.interpolate(&a, &b, 0.5, &mut fast);
            assert!(fast[3].is_nan());
        }
    }

    #[test]
    fn interpolation_takes_the_short_way_round() {
        let sut = Robot::builtin("fetch").unwrap();
        let a = [0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0];
        let b = [0.0, 0.0, 0.0, -3.0, 0.0, 0.0, 0.0, 0.0];
        let mut mid = [0.0; 8];
        sut.interpolate(&a, &b, 0.5, &mut mid);
        assert!((mid[3].abs() - PI).abs() < 1e-9);
    }
}
