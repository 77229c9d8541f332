//! Timing the returned path: a trajectory under the robot's limits whose blended corners are
//! checked on the exact geometry, like the path itself.

use super::validity::Validity;
use crate::trajectory::{TimingParams, Trajectory, TrajectoryError};

/// Times `path`; a corner whose blend arc touches something in the exact geometry (checked at
/// `resolution`) is narrowed, and after a few tries left sharp (the robot stops there, on the
/// validated path).
pub(super) fn timed(
    checker: &mut Validity<'_>,
    path: &[Vec<f64>],
    params: &TimingParams,
    resolution: f64,
) -> Result<Trajectory, TrajectoryError> {
    let robot = checker.robot();
    let mut deviation = vec![params.max_deviation; path.len().saturating_sub(2)];
    let dof = robot.dof();
    let (mut q, mut dq, mut ddq) = (vec![0.0; dof], vec![0.0; dof], vec![0.0; dof]);
    for round in 0.. {
        let trajectory = Trajectory::new(robot, path, params, &deviation)?;
        let blended = trajectory.path();
        let mut touching = Vec::new();
        for (corner, s0, len) in blended.arcs() {
            let steps = (len / resolution).ceil().max(1.0) as usize;
            let touches = (0..=steps).any(|k| {
                let s = s0 + len * k as f64 / steps as f64;
                blended.eval(s, s0 + len / 2.0, &mut q, &mut dq, &mut ddq);
                checker.state_contact(&q).is_some()
            });
            if touches {
                touching.push(corner);
            }
        }
        if touching.is_empty() {
            return Ok(trajectory);
        }
        for c in touching {
            deviation[c] = if round < 3 { deviation[c] / 4.0 } else { 0.0 };
        }
    }
    unreachable!("corners end sharp after four rounds")
}
