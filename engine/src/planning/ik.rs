//! Inverse kinematics: damped least squares on the geometric Jacobian, with random restarts
//! inside the joint limits, keeping only collision-free, mutually distinct solutions.

use super::{PlanError, PlannerRng, PoseGoal};
use crate::collision::ConfigCheck;
use crate::robot::{Motion, Robot};
use crate::Pose;
use nalgebra::{DMatrix, DVector, Vector3};

/// Inverse kinematics settings.
#[derive(Debug, Clone, PartialEq)]
pub struct IkParams {
    /// Restarts (the first starts from the request's start configuration).
    pub attempts: usize,
    /// Damped-least-squares iterations per restart.
    pub iterations: usize,
    /// Stop after this many distinct solutions.
    pub solutions: usize,
    /// Two solutions closer than this (configuration distance) count as one.
    pub min_separation: f64,
}

impl Default for IkParams {
    fn default() -> Self {
        IkParams {
            attempts: 100,
            iterations: 150,
            solutions: 4,
            min_separation: 0.2,
        }
    }
}

/// The chain of links from the root to `link` and, per planning variable on it, the link whose
/// joint it drives.
fn chain(robot: &Robot, link: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = link;
    loop {
        let l = &robot.links()[i];
        match l.motion {
            Motion::Revolute { variable, .. } | Motion::Prismatic { variable, .. } => {
                out.push((i, variable))
            }
            Motion::Fixed => {}
        }
        match l.parent {
            Some(p) => i = p,
            None => break,
        }
    }
    out
}

/// Position and rotation error (target − current), in the base frame.
fn error(current: &Pose, target: &Pose) -> (Vector3<f64>, Vector3<f64>) {
    let dp = target.translation.vector - current.translation.vector;
    let dr = (target.rotation * current.rotation.inverse()).scaled_axis();
    (dp, dr)
}

/// Solves `goal` for up to `params.solutions` distinct collision-free configurations.
/// The first restart begins at `seed` when given.
pub fn solve<'a>(
    checker: &mut impl ConfigCheck<'a>,
    goal: &PoseGoal,
    seed: Option<&[f64]>,
    params: &IkParams,
    rng: &mut PlannerRng,
) -> Result<Vec<Vec<f64>>, PlanError> {
    let robot = checker.robot();
    let link = match &goal.link {
        Some(name) => robot
            .link_index(name)
            .ok_or_else(|| PlanError::UnknownLink(name.clone()))?,
        None => robot.tip(),
    };
    let joints = chain(robot, link);
    let use_rotation = goal.orientation_tolerance.is_finite();
    let rows = if use_rotation { 6 } else { 3 };
    let dof = robot.dof();
    let mut poses = vec![Pose::identity(); robot.links().len()];
    let mut solutions: Vec<Vec<f64>> = Vec::new();
    let mut q = vec![0.0; dof];
    let lambda2 = 0.05f64 * 0.05;
    for attempt in 0..params.attempts {
        match (attempt, seed) {
            (0, Some(s)) => q.copy_from_slice(s),
            _ => robot.sample_uniform(rng, &mut q),
        }
        for _ in 0..params.iterations {
            robot.forward_kinematics(&q, &mut poses);
            let (dp, dr) = error(&poses[link], &goal.pose);
            let pos_ok = dp.norm() <= goal.position_tolerance;
            let rot_ok = !use_rotation || dr.norm() <= goal.orientation_tolerance;
            if pos_ok && rot_ok {
                let distinct = solutions
                    .iter()
                    .all(|s| robot.distance(s, &q) >= params.min_separation);
                if distinct && checker.is_valid(&q) {
                    solutions.push(q.clone());
                }
                break;
            }
            // Geometric Jacobian of the link origin.
            let p = poses[link].translation.vector;
            let mut jac = DMatrix::<f64>::zeros(rows, dof);
            for &(li, var) in &joints {
                let frame = &poses[li];
                match robot.links()[li].motion {
                    Motion::Revolute { axis, .. } => {
                        let a = frame.rotation * axis.into_inner();
                        let v = a.cross(&(p - frame.translation.vector));
                        jac.fixed_view_mut::<3, 1>(0, var).copy_from(&v);
                        if use_rotation {
                            jac.fixed_view_mut::<3, 1>(3, var).copy_from(&a);
                        }
                    }
                    Motion::Prismatic { axis, .. } => {
                        let a = frame.rotation * axis.into_inner();
                        jac.fixed_view_mut::<3, 1>(0, var).copy_from(&a);
                    }
                    Motion::Fixed => {}
                }
            }
            let mut e = DVector::<f64>::zeros(rows);
            e.fixed_rows_mut::<3>(0).copy_from(&dp);
            if use_rotation {
                e.fixed_rows_mut::<3>(3).copy_from(&dr);
            }
            let jjt = &jac * jac.transpose() + DMatrix::<f64>::identity(rows, rows) * lambda2;
            let Some(y) = jjt.lu().solve(&e) else { break };
            let mut dq = jac.transpose() * y;
            let n = dq.norm();
            if n > 0.5 {
                dq *= 0.5 / n;
            }
            for i in 0..dof {
                q[i] += dq[i];
            }
            robot.enforce_bounds(&mut q);
        }
        if solutions.len() >= params.solutions {
            break;
        }
    }
    Ok(solutions)
}
