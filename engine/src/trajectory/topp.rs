//! Time-optimal parameterisation of a path under joint velocity and acceleration limits, by
//! reachability analysis (TOPP-RA, Pham & Pham 2018) on a grid of arc lengths.
//!
//! With `x = ṡ²` and `u = s̈`, joint velocities are `q'(s) ṡ` and accelerations
//! `q'(s) u + q''(s) x`: the limits are linear in `(x, u)`. Between grid points `u` is
//! constant, so `x` is linear in `s` (exact on straight pieces). Velocity limits hold
//! everywhere (each interval is bounded by the largest joint speed factor anywhere in it);
//! acceleration limits are imposed at both ends of every grid interval, exact on straight
//! pieces; inside the arcs of blended corners (intervals of 0.03 rad of turn) they may be
//! exceeded between grid points by a hair (the tests allow 0.5%; measured worst 0.02%). A
//! backward pass computes, per grid point, the interval of `x` from which the end can still
//! be reached at rest; a forward pass then takes the largest `u` that stays within them.

use super::path::BlendedPath;

/// The optimal parameterisation: per grid point, arc length `s` and `x = ṡ²`; per interval,
/// `u = s̈`.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// Grid arc lengths.
    pub s: Vec<f64>,
    /// Squared path speed at each grid point.
    pub x: Vec<f64>,
    /// Path acceleration over each interval.
    pub u: Vec<f64>,
    /// Time at each grid point.
    pub t: Vec<f64>,
}

/// Why no parameterisation exists.
#[derive(Debug, Clone, PartialEq)]
pub enum ProfileError {
    /// The path cannot be followed from rest at arc length `s` (a limit of zero there).
    Stuck {
        /// Arc length where the path cannot be followed.
        s: f64,
    },
}

/// Grid spacing on straight pieces (arc length), and on arcs (angle turned, radians).
const LINE_STEP: f64 = 0.05;
const ARC_STEP: f64 = 0.03;

/// The grid: piece boundaries, plus subdivisions.
fn grid(path: &BlendedPath) -> Vec<f64> {
    let mut s = vec![0.0];
    for (s0, len, turn) in path.pieces() {
        let n = if turn > 0.0 {
            (turn / ARC_STEP).ceil().max(4.0) as usize
        } else {
            (len / LINE_STEP).ceil().max(1.0) as usize
        };
        for k in 1..n {
            s.push(s0 + len * k as f64 / n as f64);
        }
        // The piece's end exactly as the next piece's start.
        s.push(s0 + len);
    }
    s
}

/// One acceleration bound `a u + b x ∈ [-limit, limit]` of interval `i`, as lower and upper
/// bounds on `u` linear in `x` (`u ≥ p x + r` / `u ≤ p x + r`), or a bound on `x` alone.
struct Bounds {
    lower: Vec<(f64, f64)>,
    upper: Vec<(f64, f64)>,
    x_max: f64,
}

impl Bounds {
    /// Adds `-limit ≤ a u + b x ≤ limit`.
    fn add(&mut self, a: f64, b: f64, limit: f64) {
        if a.abs() > 1e-12 {
            // u between (∓limit - b x) / a, whichever way round the sign of a puts them.
            let slope = -b / a;
            let reach = limit / a.abs();
            self.lower.push((slope, -reach));
            self.upper.push((slope, reach));
        } else if b.abs() > 1e-12 {
            self.x_max = self.x_max.min(limit / b.abs());
        }
    }

    /// The interval of `x` in `[0, x_max]` for which some `u` meets every bound.
    fn feasible_x(&self, x_max: f64) -> Option<(f64, f64)> {
        let (mut lo, mut hi) = (0.0f64, x_max.min(self.x_max));
        for &(pl, rl) in &self.lower {
            for &(pu, ru) in &self.upper {
                // pl x + rl ≤ pu x + ru
                let (c, d) = (pl - pu, ru - rl);
                if c > 1e-12 {
                    hi = hi.min(d / c);
                } else if c < -1e-12 {
                    lo = lo.max(d / c);
                } else if d < -1e-9 {
                    return None;
                }
            }
        }
        (lo <= hi + 1e-12).then_some((lo, hi.max(lo)))
    }

    /// The range of `u` at `x`.
    fn u_range(&self, x: f64) -> (f64, f64) {
        let lo = self
            .lower
            .iter()
            .map(|&(p, r)| p * x + r)
            .fold(f64::NEG_INFINITY, f64::max);
        let hi = self
            .upper
            .iter()
            .map(|&(p, r)| p * x + r)
            .fold(f64::INFINITY, f64::min);
        (lo, hi)
    }
}

/// The time-optimal profile along `path` from rest to rest under per-joint `velocity` and
/// `acceleration` limits (positive).
pub fn parameterize(
    path: &BlendedPath,
    velocity: &[f64],
    acceleration: &[f64],
) -> Result<Profile, ProfileError> {
    let dof = velocity.len();
    let s = grid(path);
    let n = s.len();
    let (mut q, mut dq, mut ddq) = (vec![0.0; dof], vec![0.0; dof], vec![0.0; dof]);
    let (mut dq_end, mut ddq_end) = (vec![0.0; dof], vec![0.0; dof]);
    // Velocity bound on x per grid point: over each interval x is linear in s, so bounding it
    // at both ends by the largest |q'_j| anywhere in the interval bounds the speed throughout.
    let mut x_vel = vec![f64::INFINITY; n];
    for i in 0..n - 1 {
        let on = (s[i] + s[i + 1]) / 2.0;
        path.eval(s[i], on, &mut q, &mut dq, &mut ddq);
        path.eval(s[i + 1], on, &mut q, &mut dq_end, &mut ddq_end);
        let delta = s[i + 1] - s[i];
        let bend2: f64 = ddq.iter().map(|v| v * v).sum();
        let mut x_max = f64::INFINITY;
        for j in 0..dof {
            // On an arc q'_j is ρ cos(s/r + φ): it exceeds the larger end by at most
            // ρ Δ² / (8 r²), with ρ² = q'_j² + r² q''_j² and 1/r² = |q''|².
            let rho = if bend2 > 0.0 {
                (dq[j] * dq[j] + ddq[j] * ddq[j] / bend2).sqrt()
            } else {
                0.0
            };
            let peak = dq[j].abs().max(dq_end[j].abs()) + rho * bend2 * delta * delta / 8.0;
            x_max = x_max.min((velocity[j] / peak.max(1e-12)).powi(2));
        }
        x_vel[i] = x_vel[i].min(x_max);
        x_vel[i + 1] = x_vel[i + 1].min(x_max);
    }
    for &stop in path.stops() {
        let i = s.partition_point(|&v| v < stop - 1e-12);
        if i < n {
            x_vel[i] = 0.0;
        }
    }
    x_vel[0] = 0.0;
    x_vel[n - 1] = 0.0;
    // Per interval i (from s[i] to s[i+1]): acceleration bounds at both ends, as bounds on u.
    let mut stages: Vec<Bounds> = Vec::with_capacity(n - 1);
    for i in 0..n - 1 {
        let delta = s[i + 1] - s[i];
        // The interval lies in one piece: evaluate at its ends from inside it.
        let on = (s[i] + s[i + 1]) / 2.0;
        path.eval(s[i], on, &mut q, &mut dq, &mut ddq);
        path.eval(s[i + 1], on, &mut q, &mut dq_end, &mut ddq_end);
        let mut b = Bounds {
            lower: Vec::with_capacity(2 * dof + 1),
            upper: Vec::with_capacity(2 * dof + 1),
            x_max: f64::INFINITY,
        };
        for j in 0..dof {
            // Start: q' u + q'' x. End: q'_e u + q''_e (x + 2Δu).
            b.add(dq[j], ddq[j], acceleration[j]);
            b.add(
                dq_end[j] + 2.0 * delta * ddq_end[j],
                ddq_end[j],
                acceleration[j],
            );
        }
        stages.push(b);
    }
    // Backward: controllable intervals.
    let mut k_lo = vec![0.0; n];
    let mut k_hi = vec![0.0; n];
    for i in (0..n - 1).rev() {
        let delta = s[i + 1] - s[i];
        let b = &mut stages[i];
        // x + 2Δu ∈ [k_lo, k_hi] of the next point.
        b.lower
            .push((-1.0 / (2.0 * delta), k_lo[i + 1] / (2.0 * delta)));
        b.upper
            .push((-1.0 / (2.0 * delta), k_hi[i + 1] / (2.0 * delta)));
        let (lo, hi) = b.feasible_x(x_vel[i]).unwrap_or((0.0, 0.0));
        k_lo[i] = lo;
        k_hi[i] = hi;
    }
    // Forward: the greatest acceleration that stays controllable.
    let mut x = vec![0.0; n];
    let mut u = vec![0.0; n - 1];
    let mut t = vec![0.0; n];
    for i in 0..n - 1 {
        let delta = s[i + 1] - s[i];
        let (lo, hi) = stages[i].u_range(x[i]);
        let ui = hi.max(lo);
        let next = (x[i] + 2.0 * delta * ui)
            .clamp(k_lo[i + 1], k_hi[i + 1])
            .max(0.0);
        u[i] = (next - x[i]) / (2.0 * delta);
        x[i + 1] = next;
        let speed = x[i].sqrt() + next.sqrt();
        if speed <= 1e-12 {
            return Err(ProfileError::Stuck { s: s[i] });
        }
        t[i + 1] = t[i] + 2.0 * delta / speed;
    }
    Ok(Profile { s, x, u, t })
}
