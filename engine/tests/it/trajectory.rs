//! Timed trajectories: limits hold when sampled at 1 kHz, waypoints are passed within the
//! blend deviation, rest to rest, and bad input gets its own error.

use ember_engine::robot::Robot;
use ember_engine::trajectory::{time_parameterize, TimingParams, Trajectory, TrajectoryError};
use rand::{Rng, SeedableRng};

/// Relative slack on acceleration limits between the grid points of blend arcs (velocity
/// limits hold exactly).
const TOLERANCE: f64 = 0.005;

/// A random path of `n` waypoints within the joint limits.
fn random_path(robot: &Robot, rng: &mut impl Rng, n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| {
            robot
                .variables()
                .iter()
                .map(|v| rng.random_range(v.lower..v.upper))
                .collect()
        })
        .collect()
}

struct Worst {
    velocity: f64,
    acceleration: f64,
    finite_difference: f64,
}

/// Samples `t` at 1 kHz and returns the worst ratios to the limits.
fn check(robot: &Robot, t: &Trajectory, path: &[Vec<f64>], params: &TimingParams) -> Worst {
    let dof = robot.dof();
    let limits = robot.limits();
    let vmax: Vec<f64> = limits
        .iter()
        .map(|l| l.velocity.unwrap() * params.velocity_scaling)
        .collect();
    let amax: Vec<f64> = limits
        .iter()
        .map(|l| {
            l.acceleration.unwrap_or(params.default_acceleration) * params.acceleration_scaling
        })
        .collect();
    let mut worst = Worst {
        velocity: 0.0,
        acceleration: 0.0,
        finite_difference: 0.0,
    };
    let steps = (t.duration * 1000.0).ceil() as usize;
    let h = 1e-4;
    for k in 0..=steps {
        let time = (k as f64 / 1000.0).min(t.duration);
        let (q, dq, ddq) = t.state_at(time);
        for j in 0..dof {
            let v = &robot.variables()[j];
            if !v.continuous {
                assert!(q[j] >= v.lower - 1e-6 && q[j] <= v.upper + 1e-6, "position");
            }
            worst.velocity = worst.velocity.max(dq[j].abs() / vmax[j]);
            worst.acceleration = worst.acceleration.max(ddq[j].abs() / amax[j]);
        }
        // The velocity is the derivative of the position.
        if time > h && time < t.duration - h {
            let (a, _, _) = t.state_at(time - h);
            let (b, _, _) = t.state_at(time + h);
            for j in 0..dof {
                let fd = (b[j] - a[j]) / (2.0 * h);
                worst.finite_difference = worst.finite_difference.max((fd - dq[j]).abs() / vmax[j]);
            }
        }
    }
    // Rest to rest, from the first waypoint to the last.
    let first = &t.velocities[0];
    let last = t.velocities.last().unwrap();
    assert!(
        first.iter().chain(last).all(|v| v.abs() < 1e-9),
        "not at rest"
    );
    let end = t.positions.last().unwrap();
    assert!(
        robot.distance(end, path.last().unwrap()) < 1e-9,
        "does not end at the goal"
    );
    assert!(robot.distance(&t.positions[0], &path[0]) < 1e-12);
    // Every waypoint passed within the blend deviation, in order.
    for (i, w) in path.iter().enumerate() {
        let (q, _, _) = t.state_at(t.waypoint_times[i]);
        let d = robot.distance(&q, w);
        assert!(
            d <= params.max_deviation + 1e-6,
            "waypoint {i} missed by {d}"
        );
    }
    assert!(t.waypoint_times.windows(2).all(|w| w[0] <= w[1]));
    worst
}

#[test]
fn sampled_at_1khz_the_limits_hold_and_the_waypoints_are_passed() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let mut worst = Worst {
        velocity: 0.0,
        acceleration: 0.0,
        finite_difference: 0.0,
    };
    for name in ["fetch", "panda"] {
        let robot = Robot::builtin(name).unwrap();
        for case in 0..12 {
            let path = random_path(&robot, &mut rng, 2 + case % 9);
            let params = TimingParams {
                velocity_scaling: [1.0, 0.5, 0.1][case % 3],
                acceleration_scaling: [1.0, 0.3][case % 2],
                max_deviation: [0.05, 0.0, 0.2][case % 3],
                ..TimingParams::default()
            };
            let t = time_parameterize(&robot, &path, &params).unwrap();
            let w = check(&robot, &t, &path, &params);
            worst.velocity = worst.velocity.max(w.velocity);
            worst.acceleration = worst.acceleration.max(w.acceleration);
            worst.finite_difference = worst.finite_difference.max(w.finite_difference);
        }
    }
    assert!(
        worst.velocity <= 1.0 + TOLERANCE,
        "velocity at {:.4} of its limit",
        worst.velocity
    );
    assert!(
        worst.acceleration <= 1.0 + TOLERANCE,
        "acceleration at {:.4} of its limit",
        worst.acceleration
    );
    assert!(
        worst.finite_difference < 1e-3,
        "velocity is not the position's derivative"
    );
    // The limits are reached (the trajectory is not merely slow).
    assert!(worst.velocity > 0.9 && worst.acceleration > 0.9);
}

#[test]
fn bad_input_gets_one_sentence_naming_what_is_wrong() {
    let robot = Robot::builtin("fetch").unwrap();
    let a = robot.named_state("stow").unwrap().to_vec();
    let ok = TimingParams::default();
    let err = |path: &[Vec<f64>], params: &TimingParams| {
        time_parameterize(&robot, path, params).unwrap_err()
    };
    let scaled = TimingParams {
        velocity_scaling: 1.5,
        ..ok
    };
    assert!(matches!(
        err(std::slice::from_ref(&a), &scaled),
        TrajectoryError::Parameter { .. }
    ));
    assert_eq!(
        err(
            std::slice::from_ref(&a),
            &TimingParams {
                acceleration_scaling: 0.0,
                ..ok
            }
        )
        .to_string(),
        "acceleration scaling factor 0 is outside (0, 1]"
    );
    let mut nan = a.clone();
    nan[2] = f64::NAN;
    assert!(err(&[a.clone(), nan], &ok)
        .to_string()
        .contains("non-finite value NaN for joint 'shoulder_lift_joint'"));
    let mut far = a.clone();
    far[0] = 2.0;
    assert!(err(&[a.clone(), far], &ok)
        .to_string()
        .contains("'torso_lift_joint' at 2"));
    assert_eq!(err(&[], &ok), TrajectoryError::EmptyPath);
    assert!(matches!(
        err(&[vec![0.0; 3]], &ok),
        TrajectoryError::WrongLength { .. }
    ));
}

#[test]
fn a_single_waypoint_is_a_trajectory_at_rest() {
    let robot = Robot::builtin("panda").unwrap();
    let a = robot.named_state("ready").unwrap().to_vec();
    let t = time_parameterize(&robot, &[a.clone(), a.clone()], &TimingParams::default()).unwrap();
    assert_eq!(t.duration, 0.0);
    assert_eq!(t.positions, vec![a]);
}
