//! Executable trajectories: a planned path timed under the robot's joint velocity and
//! acceleration limits, from rest to rest, as a controller needs it.
//!
//! The path's corners are blended by circular arcs ([`BlendedPath`]) so the robot does not
//! stop at every waypoint, then timed optimally ([`topp`]: reachability analysis, as TOPP-RA
//! does), then sampled at a fixed period with positions, velocities and accelerations, plus
//! the time each waypoint is passed. Continuous joints are unwrapped: positions run on from
//! the start's value without jumps of 2π.
//!
//! ```
//! use ember_engine::robot::Robot;
//! use ember_engine::trajectory::{time_parameterize, TimingParams};
//! let robot = Robot::builtin("panda").unwrap();
//! let a = robot.named_state("ready").unwrap().to_vec();
//! let mut b = a.clone();
//! b[0] += 1.0;
//! let mut c = b.clone();
//! c[3] += 0.5;
//! let t = time_parameterize(&robot, &[a, b, c], &TimingParams::default()).unwrap();
//! assert!(t.duration > 0.5 && t.duration < 5.0);
//! assert_eq!(t.velocities.last().unwrap().iter().map(|v| v.abs()).sum::<f64>(), 0.0);
//! ```

pub mod path;
pub mod topp;

pub use path::BlendedPath;

use crate::robot::config_space::LIMIT_TOLERANCE;
use crate::robot::Robot;
use thiserror::Error;

/// How a path is timed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimingParams {
    /// Fraction of every joint's velocity limit used, in (0, 1] (MoveIt's
    /// `max_velocity_scaling_factor`).
    pub velocity_scaling: f64,
    /// Fraction of every joint's acceleration limit used, in (0, 1].
    pub acceleration_scaling: f64,
    /// How far (configuration-space distance) a blended corner may pass from its waypoint;
    /// 0 stops at every waypoint.
    pub max_deviation: f64,
    /// Sampling period of the output, seconds.
    pub sample_period: f64,
    /// Acceleration limit of joints the description gives none (rad/s² or m/s²).
    pub default_acceleration: f64,
}

impl TimingParams {
    /// `Err` naming the first parameter out of range.
    pub fn validate(&self) -> Result<(), TrajectoryError> {
        check_params(self)
    }
}

impl Default for TimingParams {
    fn default() -> Self {
        TimingParams {
            velocity_scaling: 1.0,
            acceleration_scaling: 1.0,
            max_deviation: 0.05,
            sample_period: 0.1,
            default_acceleration: 1.0,
        }
    }
}

/// Why a path could not be timed. Each names what is wrong.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TrajectoryError {
    /// A timing parameter is out of range.
    #[error("{name} {value} is outside {range}")]
    Parameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range.
        range: &'static str,
    },
    /// A joint has no velocity limit.
    #[error("joint '{joint}' has no velocity limit (give one in the URDF's <limit velocity>, the robot file's [joint_limits] or a joint_limits.yaml)")]
    MissingVelocityLimit {
        /// Joint name.
        joint: String,
    },
    /// A joint's limit is zero, negative or not a number.
    #[error("joint '{joint}' has an unusable {kind} limit {value} (must be positive and finite)")]
    BadLimit {
        /// Joint name.
        joint: String,
        /// `velocity` or `acceleration`.
        kind: &'static str,
        /// The limit.
        value: f64,
    },
    /// The path has no waypoint.
    #[error("the path has no waypoint")]
    EmptyPath,
    /// A waypoint has the wrong number of values.
    #[error("waypoint {waypoint} has {got} values, the robot has {expected} joints")]
    WrongLength {
        /// Waypoint number.
        waypoint: usize,
        /// Values given.
        got: usize,
        /// Joints planned.
        expected: usize,
    },
    /// A waypoint holds NaN or an infinity.
    #[error("waypoint {waypoint} has a non-finite value {value} for joint '{joint}'")]
    NonFinite {
        /// Waypoint number.
        waypoint: usize,
        /// Joint name.
        joint: String,
        /// The value.
        value: f64,
    },
    /// A waypoint is outside a joint's position limits.
    #[error("waypoint {waypoint} puts joint '{joint}' at {value}, outside its limits [{lower}, {upper}]")]
    OutsideLimits {
        /// Waypoint number.
        waypoint: usize,
        /// Joint name.
        joint: String,
        /// The value.
        value: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// The limits leave the path no way forward.
    #[error("the path cannot be followed past arc length {s:.4} under the limits")]
    Stuck {
        /// Where.
        s: f64,
    },
}

/// A timed trajectory (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Joint names, in the columns' order.
    pub joint_names: Vec<String>,
    /// Sample times from 0, every `sample_period`, and the end.
    pub times: Vec<f64>,
    /// Positions per sample.
    pub positions: Vec<Vec<f64>>,
    /// Velocities per sample.
    pub velocities: Vec<Vec<f64>>,
    /// Accelerations per sample.
    pub accelerations: Vec<Vec<f64>>,
    /// When each waypoint of the path is passed (nearest point of a blended corner).
    pub waypoint_times: Vec<f64>,
    /// Total duration, seconds.
    pub duration: f64,
    path: BlendedPath,
    profile: topp::Profile,
}

/// Times `path` (waypoints of `robot`'s planning group) with `params`, every corner blended
/// within `params.max_deviation`.
pub fn time_parameterize(
    robot: &Robot,
    path: &[Vec<f64>],
    params: &TimingParams,
) -> Result<Trajectory, TrajectoryError> {
    let corners = vec![params.max_deviation; path.len().saturating_sub(2)];
    Trajectory::new(robot, path, params, &corners)
}

impl Trajectory {
    /// Times `path` with corner `i` (waypoint `i + 1`) blended within `deviation[i]` (for
    /// callers that narrow blends which would touch something).
    pub fn new(
        robot: &Robot,
        path: &[Vec<f64>],
        params: &TimingParams,
        deviation: &[f64],
    ) -> Result<Self, TrajectoryError> {
        params.validate()?;
        let (velocity, acceleration) = scaled_limits(robot, params)?;
        let waypoints = unwrapped(robot, path)?;
        let blended = BlendedPath::new(&waypoints, deviation);
        let profile = if blended.length() > 0.0 {
            topp::parameterize(&blended, &velocity, &acceleration)
                .map_err(|topp::ProfileError::Stuck { s }| TrajectoryError::Stuck { s })?
        } else {
            topp::Profile {
                s: vec![0.0],
                x: vec![0.0],
                u: Vec::new(),
                t: vec![0.0],
            }
        };
        let duration = *profile.t.last().expect("the grid has a point");
        let mut out = Trajectory {
            joint_names: robot.variables().iter().map(|v| v.name.clone()).collect(),
            times: Vec::new(),
            positions: Vec::new(),
            velocities: Vec::new(),
            accelerations: Vec::new(),
            waypoint_times: Vec::new(),
            duration,
            path: blended,
            profile,
        };
        if out.path.length() == 0.0 {
            // Nothing to move: one sample at the start, at rest.
            let dof = robot.dof();
            out.times = vec![0.0];
            out.positions = vec![waypoints[0].clone()];
            out.velocities = vec![vec![0.0; dof]];
            out.accelerations = vec![vec![0.0; dof]];
            out.waypoint_times = vec![0.0; path.len()];
            return Ok(out);
        }
        let n = (duration / params.sample_period).floor() as usize;
        let mut times: Vec<f64> = (0..=n).map(|k| k as f64 * params.sample_period).collect();
        if duration - times[n] > 1e-9 {
            times.push(duration);
        }
        for &t in &times {
            let (q, dq, ddq) = out.state_at(t);
            out.positions.push(q);
            out.velocities.push(dq);
            out.accelerations.push(ddq);
        }
        out.times = times;
        out.waypoint_times = out
            .path
            .waypoint_s()
            .to_vec()
            .into_iter()
            .map(|s| out.time_at(s))
            .collect();
        Ok(out)
    }

    /// The geometric path followed (waypoints unwrapped, corners blended).
    pub fn path(&self) -> &BlendedPath {
        &self.path
    }

    /// Position, velocity and acceleration at time `t` (clamped to `[0, duration]`).
    pub fn state_at(&self, t: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let dof = self.joint_names.len();
        let (mut q, mut dq, mut ddq) = (vec![0.0; dof], vec![0.0; dof], vec![0.0; dof]);
        let p = &self.profile;
        let t = t.clamp(0.0, self.duration);
        if p.u.is_empty() {
            self.path.eval(0.0, 0.0, &mut q, &mut dq, &mut ddq);
            return (q, vec![0.0; dof], vec![0.0; dof]);
        }
        let i = p.t.partition_point(|&ti| ti <= t).clamp(1, p.u.len()) - 1;
        let tau = t - p.t[i];
        let (u, v0) = (p.u[i], p.x[i].sqrt());
        let (s, v) = if t >= self.duration {
            // The end exactly, at rest (no rounding left in the speed).
            (p.s[i + 1], 0.0)
        } else {
            let s = (p.s[i] + v0 * tau + 0.5 * u * tau * tau).clamp(p.s[i], p.s[i + 1]);
            (s, (v0 + u * tau).max(0.0))
        };
        let on = (p.s[i] + p.s[i + 1]) / 2.0;
        self.path.eval(s, on, &mut q, &mut dq, &mut ddq);
        for j in 0..dof {
            let (tangent, curvature) = (dq[j], ddq[j]);
            dq[j] = tangent * v;
            ddq[j] = tangent * u + curvature * v * v;
        }
        (q, dq, ddq)
    }

    /// When the path passes arc length `s`.
    fn time_at(&self, s: f64) -> f64 {
        let p = &self.profile;
        let i = p.s.partition_point(|&si| si <= s).clamp(1, p.u.len()) - 1;
        let (u, v0, d) = (p.u[i], p.x[i].sqrt(), (s - p.s[i]).max(0.0));
        let tau = if u.abs() < 1e-12 {
            if v0 > 0.0 {
                d / v0
            } else {
                0.0
            }
        } else {
            ((v0 * v0 + 2.0 * u * d).max(0.0).sqrt() - v0) / u
        };
        (p.t[i] + tau).min(p.t[i + 1])
    }
}

fn check_params(p: &TimingParams) -> Result<(), TrajectoryError> {
    let unit = |name, value: f64| {
        if value > 0.0 && value <= 1.0 {
            Ok(())
        } else {
            Err(TrajectoryError::Parameter {
                name,
                value,
                range: "(0, 1]",
            })
        }
    };
    unit("velocity scaling factor", p.velocity_scaling)?;
    unit("acceleration scaling factor", p.acceleration_scaling)?;
    let positive = |name, value: f64, range| {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(TrajectoryError::Parameter { name, value, range })
        }
    };
    positive("sample period", p.sample_period, "(0, ∞) seconds")?;
    positive(
        "default acceleration",
        p.default_acceleration,
        "(0, ∞) per second²",
    )?;
    if !(p.max_deviation.is_finite() && p.max_deviation >= 0.0) {
        return Err(TrajectoryError::Parameter {
            name: "blend deviation",
            value: p.max_deviation,
            range: "[0, ∞)",
        });
    }
    Ok(())
}

/// Per joint: the velocity and acceleration limits, scaled.
fn scaled_limits(
    robot: &Robot,
    params: &TimingParams,
) -> Result<(Vec<f64>, Vec<f64>), TrajectoryError> {
    let mut velocity = Vec::with_capacity(robot.dof());
    let mut acceleration = Vec::with_capacity(robot.dof());
    for (v, l) in robot.variables().iter().zip(robot.limits()) {
        let bad = |kind, value| TrajectoryError::BadLimit {
            joint: v.name.clone(),
            kind,
            value,
        };
        let vel = l
            .velocity
            .ok_or_else(|| TrajectoryError::MissingVelocityLimit {
                joint: v.name.clone(),
            })?;
        if !(vel.is_finite() && vel > 0.0) {
            return Err(bad("velocity", vel));
        }
        let acc = l.acceleration.unwrap_or(params.default_acceleration);
        if !(acc.is_finite() && acc > 0.0) {
            return Err(bad("acceleration", acc));
        }
        velocity.push(vel * params.velocity_scaling);
        acceleration.push(acc * params.acceleration_scaling);
    }
    Ok((velocity, acceleration))
}

/// The waypoints checked, continuous joints unwrapped (each step the short way round).
fn unwrapped(robot: &Robot, path: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, TrajectoryError> {
    if path.is_empty() {
        return Err(TrajectoryError::EmptyPath);
    }
    let vars = robot.variables();
    for (i, w) in path.iter().enumerate() {
        if w.len() != vars.len() {
            return Err(TrajectoryError::WrongLength {
                waypoint: i,
                got: w.len(),
                expected: vars.len(),
            });
        }
        for (v, &value) in vars.iter().zip(w) {
            if !value.is_finite() {
                return Err(TrajectoryError::NonFinite {
                    waypoint: i,
                    joint: v.name.clone(),
                    value,
                });
            }
            if !v.continuous
                && (value < v.lower - LIMIT_TOLERANCE || value > v.upper + LIMIT_TOLERANCE)
            {
                return Err(TrajectoryError::OutsideLimits {
                    waypoint: i,
                    joint: v.name.clone(),
                    value,
                    lower: v.lower,
                    upper: v.upper,
                });
            }
        }
    }
    let mut out = vec![path[0].clone()];
    for w in &path[1..] {
        let last = out.last().expect("one waypoint at least");
        let next = (0..w.len())
            .map(|j| last[j] + robot.joint_delta(j, last[j], w[j]))
            .collect();
        out.push(next);
    }
    Ok(out)
}
