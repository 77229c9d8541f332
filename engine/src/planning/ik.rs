//! Inverse kinematics: damped least squares on the geometric Jacobian, with random restarts
//! inside the joint limits, keeping only collision-free, mutually distinct solutions.

use super::{PlanError, PlannerRng, PoseGoal};
use crate::collision::ConfigCheck;
use crate::robot::{Motion, Robot};
use crate::Pose;
use nalgebra::{Matrix6, Vector3, Vector6};

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
pub(crate) fn chain(robot: &Robot, link: usize) -> Vec<(usize, usize)> {
    robot
        .ancestry(link)
        .filter_map(|i| match robot.links()[i].motion {
            Motion::Revolute { variable, .. } | Motion::Prismatic { variable, .. } => {
                Some((i, variable))
            }
            Motion::Fixed => None,
        })
        .collect()
}

/// The geometric Jacobian of `link`'s origin at `poses` (forward kinematics of the chain
/// `joints`, see [`chain`]): per planning variable, its column (linear velocity, then angular
/// velocity, the latter left zero unless `rotation`).
pub(crate) fn jacobian(
    robot: &Robot,
    poses: &[Pose],
    joints: &[(usize, usize)],
    link: usize,
    rotation: bool,
    jac: &mut [Vector6<f64>],
) {
    let p = poses[link].translation.vector;
    jac.fill(Vector6::zeros());
    for &(li, var) in joints {
        let frame = &poses[li];
        let column = &mut jac[var];
        match robot.links()[li].motion {
            Motion::Revolute { axis, .. } => {
                let a = frame.rotation * axis.into_inner();
                let v = a.cross(&(p - frame.translation.vector));
                column.fixed_rows_mut::<3>(0).copy_from(&v);
                if rotation {
                    column.fixed_rows_mut::<3>(3).copy_from(&a);
                }
            }
            Motion::Prismatic { axis, .. } => {
                let a = frame.rotation * axis.into_inner();
                column.fixed_rows_mut::<3>(0).copy_from(&a);
            }
            Motion::Fixed => {}
        }
    }
}

/// The damped least-squares step `dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e` for the Jacobian's columns `jac`
/// and the error `e`, written into `dq`; false when the system cannot be solved.
pub(crate) fn damped_step(
    jac: &[Vector6<f64>],
    e: &Vector6<f64>,
    lambda2: f64,
    dq: &mut [f64],
) -> bool {
    let mut jjt = Matrix6::identity() * lambda2;
    for c in jac {
        jjt.ger(1.0, c, c, 1.0);
    }
    let Some(y) = jjt.cholesky().map(|c| c.solve(e)) else {
        return false;
    };
    for (d, c) in dq.iter_mut().zip(jac) {
        *d = c.dot(&y);
    }
    true
}

/// Position and rotation error (target − current), in the base frame.
pub(crate) fn error(current: &Pose, target: &Pose) -> (Vector3<f64>, Vector3<f64>) {
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
    let dof = robot.dof();
    let mut poses = vec![Pose::identity(); robot.links().len()];
    let mut solutions: Vec<Vec<f64>> = Vec::new();
    let mut q = vec![0.0; dof];
    // Per variable, its column of the Jacobian (rotation rows zero for a position goal, which
    // leaves those rows of the step's system at the damping alone: the position's 3×3 system).
    let mut jac = vec![Vector6::<f64>::zeros(); dof];
    let mut dq = vec![0.0; dof];
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
            jacobian(robot, &poses, &joints, link, use_rotation, &mut jac);
            let mut e = Vector6::zeros();
            e.fixed_rows_mut::<3>(0).copy_from(&dp);
            if use_rotation {
                e.fixed_rows_mut::<3>(3).copy_from(&dr);
            }
            if !damped_step(&jac, &e, lambda2, &mut dq) {
                break;
            }
            let n = dq.iter().map(|d| d * d).sum::<f64>().sqrt();
            let scale = if n > 0.5 { 0.5 / n } else { 1.0 };
            for (qi, d) in q.iter_mut().zip(&dq) {
                *qi += d * scale;
            }
            robot.enforce_bounds(&mut q);
        }
        if solutions.len() >= params.solutions {
            break;
        }
    }
    Ok(solutions)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::exact::ExactChecker;
    use crate::world::Environment;
    use rand::SeedableRng;

    /// Poses the tip reaches at random configurations are solved within tolerance, with and
    /// without the orientation, on Fetch (a prismatic torso) and the Panda.
    #[test]
    fn reachable_poses_are_solved_within_tolerance() {
        let env = Environment::new();
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let mut checker = ExactChecker::new(&robot, &env);
            let mut rng = PlannerRng::seed_from_u64(8);
            let mut q = vec![0.0; robot.dof()];
            for with_rotation in [true, false] {
                let mut solved = 0;
                for _ in 0..20 {
                    robot.sample_uniform(&mut rng, &mut q);
                    let goal = PoseGoal {
                        link: None,
                        pose: robot.tip_pose(&q).unwrap(),
                        position_tolerance: 0.002,
                        orientation_tolerance: if with_rotation { 0.01 } else { f64::INFINITY },
                    };
                    let params = IkParams {
                        solutions: 1,
                        ..IkParams::default()
                    };
                    let sols = solve(&mut checker, &goal, None, &params, &mut rng).unwrap();
                    for s in &sols {
                        let tip = robot.tip_pose(s).unwrap();
                        let dp = tip.translation.vector - goal.pose.translation.vector;
                        assert!(dp.norm() <= 0.002);
                        if with_rotation {
                            assert!(tip.rotation.angle_to(&goal.pose.rotation) <= 0.01);
                        }
                        assert!(checker.is_valid(s));
                    }
                    solved += usize::from(!sols.is_empty());
                }
                // A random configuration may collide with the robot itself: most do not.
                assert!(
                    solved >= 14,
                    "{name}, rotation {with_rotation}: {solved} of 20"
                );
            }
        }
    }
}
