//! Decoding a plan request: every check of the wire form, into engine terms or a typed
//! [`Rejection`].

use crate::config::Config;
use crate::service::rejection::Rejection;
use ember_engine::experience::Method;
use ember_engine::planning::{Goal, PlanRequest, PlannerParams, PoseGoal};
use ember_engine::robot::Robot;
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_engine::trajectory::TimingParams;
use ember_sdk::wire::{self, GoalKind, PlanRequestHeader};
use std::time::Duration;

/// A request decoded into engine terms.
pub struct Decoded {
    /// The sampling method (`auto` resolved).
    pub method: Method,
    /// The planning request.
    pub request: PlanRequest,
    /// Whether the daemon may learn from the solution.
    pub learn: bool,
}

/// The engine method a wire method code asks for (`auto`: `default`).
pub fn method_of(code: u32, default: Method) -> Result<Method, Rejection> {
    use ember_sdk::wire::Method as M;
    Ok(match code {
        c if c == M::Auto as u32 => default,
        c if c == M::Uniform as u32 => Method::Uniform,
        c if c == M::Spark as u32 => Method::Spark,
        c if c == M::Flame as u32 => Method::Flame,
        c => return Err(Rejection::UnknownMethod(c)),
    })
}

/// The wire code of an engine method.
pub fn method_code(m: Method) -> u32 {
    use ember_sdk::wire::Method as M;
    (match m {
        Method::Uniform => M::Uniform,
        Method::Spark => M::Spark,
        Method::Flame => M::Flame,
    }) as u32
}

/// Checks a request (header `h`, payload `values`) and turns it into an engine request;
/// `auto` becomes `default_method`.
pub fn decode(
    config: &Config,
    robot: &Robot,
    default_method: Method,
    h: &PlanRequestHeader,
    values: &[f64],
) -> Result<Decoded, Rejection> {
    Rejection::check_version("request", h.version)?;
    let dof = robot.dof();
    Rejection::check_dof("request", h.dof, dof)?;
    let goal_kind = match h.goal_kind {
        k if k == GoalKind::Joints as u32 => GoalKind::Joints,
        k if k == GoalKind::Pose as u32 => GoalKind::Pose,
        k => return Err(Rejection::UnknownGoalKind(k)),
    };
    let method = method_of(h.method, default_method)?;
    if h.flags & !wire::KNOWN_FLAGS != 0 {
        return Err(Rejection::UnknownFlags(h.flags & !wire::KNOWN_FLAGS));
    }
    let goals = if goal_kind == GoalKind::Joints {
        h.goal_count as usize
    } else {
        0
    };
    if goal_kind == GoalKind::Joints && goals == 0 {
        return Err(Rejection::NoGoal);
    }
    let timed = h.flags & wire::FLAG_TRAJECTORY != 0;
    let expected = dof * (1 + goals) + if timed { 2 } else { 0 };
    if values.len() != expected {
        return Err(Rejection::PayloadLength {
            found: values.len(),
            expected,
            configurations: 1 + goals,
            dof,
            timed,
        });
    }
    let numbers = values.iter().chain(&h.pose).chain([
        &h.time_limit_s,
        &h.position_tolerance,
        &h.orientation_tolerance,
    ]);
    if numbers.clone().any(|v| !v.is_finite()) {
        return Err(Rejection::NotFinite);
    }
    let timing = if timed {
        // 0 keeps the configured factor; anything else must be in (0, 1].
        let configured = config.trajectory.params();
        let pick = |v: f64, default: f64| if v == 0.0 { default } else { v };
        let n = values.len();
        let timing = TimingParams {
            velocity_scaling: pick(values[n - 2], configured.velocity_scaling),
            acceleration_scaling: pick(values[n - 1], configured.acceleration_scaling),
            ..configured
        };
        timing
            .validate()
            .map_err(|e| Rejection::Timing(e.to_string()))?;
        Some(timing)
    } else {
        None
    };
    let start = values[..dof].to_vec();
    let goal = match goal_kind {
        GoalKind::Joints => Goal::Joints(
            values[dof..dof * (1 + goals)]
                .chunks_exact(dof)
                .map(<[f64]>::to_vec)
                .collect(),
        ),
        GoalKind::Pose => {
            let p = h.pose;
            let pose = pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]])
                .ok_or(Rejection::ZeroQuaternion)?;
            if !(h.position_tolerance > 0.0 && h.orientation_tolerance > 0.0) {
                return Err(Rejection::Tolerances);
            }
            Goal::Pose(PoseGoal {
                link: None,
                pose,
                position_tolerance: h.position_tolerance,
                orientation_tolerance: h.orientation_tolerance,
            })
        }
    };
    let cap = config.planner.max_time_limit_s;
    if h.time_limit_s > cap {
        return Err(Rejection::TimeLimit {
            requested: h.time_limit_s,
            cap,
        });
    }
    let time_limit = if h.time_limit_s > 0.0 {
        h.time_limit_s
    } else {
        config.planner.default_time_limit_s
    };
    Ok(Decoded {
        method,
        request: PlanRequest {
            start,
            goal,
            params: PlannerParams {
                seed: h.seed,
                time_limit: Duration::from_secs_f64(time_limit),
                range: config.planner.range,
                simplify: config.planner.simplify,
                validation_refine: config.planner.validation_refine,
                certify: config.planner.certify,
                timing,
                ..Default::default()
            },
        },
        learn: config.experience.online_learning && h.flags & wire::FLAG_NO_LEARN == 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(robot: &Robot) -> (PlanRequestHeader, Vec<f64>) {
        let dof = robot.dof();
        let h = PlanRequestHeader {
            version: wire::PROTOCOL_VERSION,
            dof: dof as u32,
            goal_kind: GoalKind::Joints as u32,
            goal_count: 1,
            method: wire::Method::Auto as u32,
            ..Default::default()
        };
        (h, vec![0.1; 2 * dof])
    }

    #[test]
    fn each_malformed_field_has_its_own_rejection() {
        let robot = Robot::builtin("fetch").unwrap();
        let config = Config::load(None).unwrap();
        let decode = |h: &PlanRequestHeader, v: &[f64]| {
            decode(&config, &robot, Method::Spark, h, v).map(|d| d.method)
        };
        let (h, v) = request(&robot);
        assert_eq!(
            decode(&h, &v),
            Ok(Method::Spark),
            "auto: the default method"
        );
        let with = |f: &dyn Fn(&mut PlanRequestHeader)| {
            let mut h = h;
            f(&mut h);
            decode(&h, &v).unwrap_err()
        };
        assert!(matches!(
            with(&|h| h.version = 99),
            Rejection::Version { found: 99, .. }
        ));
        assert!(matches!(
            with(&|h| h.dof = 7),
            Rejection::WrongDof {
                found: 7,
                expected: 8,
                ..
            }
        ));
        assert_eq!(with(&|h| h.goal_kind = 9), Rejection::UnknownGoalKind(9));
        assert_eq!(with(&|h| h.method = 9), Rejection::UnknownMethod(9));
        assert_eq!(
            with(&|h| h.flags = 1 << 30),
            Rejection::UnknownFlags(1 << 30)
        );
        assert_eq!(with(&|h| h.goal_count = 0), Rejection::NoGoal);
        assert!(matches!(
            with(&|h| h.goal_count = 2),
            Rejection::PayloadLength {
                found: 16,
                expected: 24,
                ..
            }
        ));
        assert_eq!(with(&|h| h.time_limit_s = f64::NAN), Rejection::NotFinite);
        assert_eq!(
            with(&|h| h.time_limit_s = 60.0),
            Rejection::TimeLimit {
                requested: 60.0,
                cap: 10.0
            }
        );
        assert_eq!(
            with(&|h| h.goal_kind = GoalKind::Pose as u32),
            Rejection::PayloadLength {
                found: 16,
                expected: 8,
                configurations: 1,
                dof: 8,
                timed: false
            }
        );
        let mut pose = h;
        pose.goal_kind = GoalKind::Pose as u32;
        assert_eq!(
            decode(&pose, &v[..8]).unwrap_err(),
            Rejection::ZeroQuaternion
        );
        pose.pose[6] = 1.0;
        assert_eq!(decode(&pose, &v[..8]).unwrap_err(), Rejection::Tolerances);
        // Each maps to the status code of its kind.
        assert_eq!(
            with(&|h| h.version = 99).status(),
            ember_sdk::Status::VersionMismatch
        );
        assert_eq!(with(&|h| h.dof = 7).status(), ember_sdk::Status::WrongDof);
        assert_eq!(
            with(&|h| h.method = 9).status(),
            ember_sdk::Status::BadRequest
        );
    }
}
