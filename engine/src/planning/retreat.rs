//! Retreats: straight-line moves of the tip out of a confined start or goal.
//!
//! A gripper deep in a narrow shelf leaves it almost only by backing out the way it came in,
//! and uniform samples seldom ask for that: RRT-Connect's tree at such a goal fails nearly every
//! extension (on MotionBenchMaker's bookshelf_thin, a median ~14k iterations while the trees
//! hold a few nodes). When a tree is stuck at its roots (see the search's `RETREAT_AFTER`),
//! the search moves the tip from each root along the axis directions of the tip's own frame
//! (+x, −x, +y, −y, +z, −z), its orientation held (damped least squares on the Jacobian, step
//! by step), and adds the states to that tree as far as they stay free: a direction the
//! geometry blocks ends at its first step; the first that runs its full [`LENGTH`] has found a
//! way out, and ends the retreats from that root. The states are checked like any extension,
//! so the search's guarantees are unchanged; only where it looks first is.

use super::ik::{chain, damped_step, error, jacobian};
use super::validity::Validity;
use crate::robot::Robot;
use crate::Pose;
use nalgebra::{Vector3, Vector6};

/// How far the tip retreats at most, metres.
pub const LENGTH: f64 = 0.4;

/// The tip's move between a retreat's states, metres.
pub const STEP: f64 = 0.04;

/// Damped least-squares iterations per step at most.
const TRACK_ITERATIONS: usize = 4;

/// A step is tracked when the tip is within this of its target (metres, radians).
const TRACK_TOLERANCE: (f64, f64) = (1e-3, 1e-2);

/// Damping (λ²) of the steps' least squares.
const DAMPING: f64 = 1e-4;

/// The retreats' working state for one robot (made once per search, on first use).
pub(crate) struct Retreat {
    tip: usize,
    /// The links from the root to the tip, in [`Robot::links`]'s order.
    links: Vec<usize>,
    /// Per planning variable on the chain, the link whose joint it drives (see [`chain`]).
    joints: Vec<(usize, usize)>,
    poses: Vec<Pose>,
    /// The chain's poses at the root, for each direction's start.
    root_poses: Vec<Pose>,
    jac: Vec<Vector6<f64>>,
    dq: Vec<f64>,
    q: Vec<f64>,
    prev: Vec<f64>,
    /// Per planning variable: held at a limit for the rest of the current step.
    held: Vec<bool>,
}

impl Retreat {
    /// Working state for `robot`'s tip link.
    pub(crate) fn new(robot: &Robot) -> Self {
        let tip = robot.tip();
        let mut links: Vec<usize> = robot.ancestry(tip).collect();
        links.reverse();
        let dof = robot.dof();
        Retreat {
            tip,
            links,
            joints: chain(robot, tip),
            poses: vec![Pose::identity(); robot.links().len()],
            root_poses: vec![Pose::identity(); robot.links().len()],
            jac: vec![Vector6::zeros(); dof],
            dq: vec![0.0; dof],
            q: vec![0.0; dof],
            prev: vec![0.0; dof],
            held: vec![false; dof],
        }
    }

    /// The retreats from `root` (see the module docs): calls `add(q, first)` for each state,
    /// in order along each direction, `first` on a direction's first state (its parent is
    /// `root`; the others' is the state before). A state is added when the tip reached its
    /// target, the configuration moved at most `max_step` from the state before, and the
    /// motion to it is free ([`Validity::reach_valid`]).
    pub(crate) fn run(
        &mut self,
        checker: &mut Validity<'_>,
        root: &[f64],
        max_step: f64,
        mut add: impl FnMut(&[f64], bool),
    ) {
        let robot = checker.robot();
        let steps = (LENGTH / STEP).round() as usize;
        robot.forward_kinematics_of(&self.links, root, &mut self.poses);
        for &l in &self.links {
            self.root_poses[l] = self.poses[l];
        }
        let start = self.poses[self.tip];
        'axes: for axis in 0..6 {
            self.q.copy_from_slice(root);
            for &l in &self.links {
                self.poses[l] = self.root_poses[l];
            }
            let mut d = Vector3::zeros();
            d[axis / 2] = if axis % 2 == 0 { STEP } else { -STEP };
            let d = start.rotation * d;
            for k in 1..=steps {
                let mut target = start;
                target.translation.vector += d * k as f64;
                self.prev.copy_from_slice(&self.q);
                if !self.track(robot, &target)
                    || robot.distance(&self.prev, &self.q) > max_step
                    || !checker.reach_valid(&self.prev, &self.q)
                {
                    continue 'axes;
                }
                add(&self.q, k == 1);
            }
            return;
        }
    }

    /// Moves `self.q` (whose chain poses `self.poses` holds) until the tip is at `target`;
    /// false when it does not get there. A joint a step would push past its limit is held
    /// where it is for the rest of the move, and the step solved again without it (clamping
    /// it instead would undo the same share of every step: a torso at its lowest, say).
    fn track(&mut self, robot: &Robot, target: &Pose) -> bool {
        self.held.fill(false);
        for _ in 0..TRACK_ITERATIONS {
            let (dp, dr) = error(&self.poses[self.tip], target);
            if dp.norm() <= TRACK_TOLERANCE.0 && dr.norm() <= TRACK_TOLERANCE.1 {
                return true;
            }
            jacobian(
                robot,
                &self.poses,
                &self.joints,
                self.tip,
                true,
                &mut self.jac,
            );
            let e = Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z);
            loop {
                for (column, _) in self.jac.iter_mut().zip(&self.held).filter(|(_, &h)| h) {
                    *column = Vector6::zeros();
                }
                if !damped_step(&self.jac, &e, DAMPING, &mut self.dq) {
                    return false;
                }
                let mut newly = false;
                for (i, v) in robot.variables().iter().enumerate() {
                    let x = self.q[i] + self.dq[i];
                    if !v.continuous && !self.held[i] && (x < v.lower || x > v.upper) {
                        self.held[i] = true;
                        newly = true;
                    }
                }
                if !newly {
                    break;
                }
            }
            for (qi, di) in self.q.iter_mut().zip(&self.dq) {
                *qi += di;
            }
            robot.enforce_bounds(&mut self.q);
            robot.forward_kinematics_of(&self.links, &self.q, &mut self.poses);
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::Shape;
    use crate::world::{Environment, Object};

    /// The built-in Fetch with its gripper in front of it, elbow and wrist bent.
    fn reaching() -> (Robot, Vec<f64>) {
        let robot = Robot::builtin("fetch").unwrap();
        (robot, vec![0.3, 0.0, -0.3, 0.0, 1.2, 0.0, 1.0, 0.0])
    }

    fn tip(robot: &Robot, q: &[f64]) -> Pose {
        robot.link_poses(q).unwrap()[robot.tip()]
    }

    /// The retreats from `q` in `env`, one list of states per direction that gave any.
    fn retreats(robot: &Robot, env: &Environment, q: &[f64]) -> Vec<Vec<Vec<f64>>> {
        let mut checker = Validity::new(robot, env, 1.0 / 32.0, 0.0);
        assert!(checker.is_valid(q), "the test's start is not free");
        let mut branches: Vec<Vec<Vec<f64>>> = Vec::new();
        Retreat::new(robot).run(&mut checker, q, 1.0, |state, first| {
            if first {
                branches.push(Vec::new());
            }
            branches.last_mut().unwrap().push(state.to_vec());
        });
        for state in branches.iter().flatten() {
            assert!(checker.is_valid(state), "a retreat state collides");
        }
        branches
    }

    /// The tip's displacement from `q0`'s to `q`'s, in the frame of `q0`'s tip.
    fn moved(robot: &Robot, q0: &[f64], q: &[f64]) -> Vector3<f64> {
        let (a, b) = (tip(robot, q0), tip(robot, q));
        a.rotation.inverse() * (b.translation.vector - a.translation.vector)
    }

    /// In free space the first axis (the tip frame's +x) runs the whole length, the tip on a
    /// straight line at `STEP` intervals, its orientation held, and no other direction is
    /// tried.
    #[test]
    fn in_the_open_one_direction_runs_its_full_length_in_a_straight_line() {
        let (robot, q) = reaching();
        let branches = retreats(&robot, &Environment::new(), &q);
        assert_eq!(branches.len(), 1);
        let steps = (LENGTH / STEP).round() as usize;
        assert_eq!(branches[0].len(), steps);
        let start = tip(&robot, &q);
        for (k, state) in branches[0].iter().enumerate() {
            let expected = Vector3::x() * (STEP * (k + 1) as f64);
            let off = (moved(&robot, &q, state) - expected).norm();
            assert!(
                off <= 2.0 * TRACK_TOLERANCE.0,
                "state {k} is {off} m off the line"
            );
            let turn = (tip(&robot, state).rotation * start.rotation.inverse()).angle();
            assert!(
                turn <= 2.0 * TRACK_TOLERANCE.1,
                "state {k} turned the tip by {turn} rad"
            );
        }
    }

    /// With the torso at its lowest and the wrist nearly straight (a bookshelf_thin goal),
    /// backing the tip out asks the torso to go lower still: the step holds the torso and
    /// moves the arm instead, and reaches its target.
    #[test]
    fn a_joint_at_its_limit_is_held_not_fought() {
        let robot = Robot::builtin("fetch").unwrap();
        let q = [0.001, -0.638, -0.639, 2.743, -0.689, -1.094, 0.022, -1.740];
        let mut retreat = Retreat::new(&robot);
        retreat.q.copy_from_slice(&q);
        robot.forward_kinematics_of(&retreat.links, &q, &mut retreat.poses);
        let mut target = retreat.poses[retreat.tip];
        target.translation.vector -= target.rotation * (Vector3::x() * STEP);
        assert!(
            retreat.track(&robot, &target),
            "the step did not reach its target"
        );
        assert!(retreat.held[0], "the torso was not held");
        assert_eq!(retreat.q[0], q[0]);
    }

    /// A wall just ahead of the gripper blocks the tip frame's +x: the retreat backs away
    /// from it instead, and no state comes nearer to it.
    #[test]
    fn a_wall_ahead_sends_the_retreat_elsewhere() {
        let (robot, q) = reaching();
        let start = tip(&robot, &q);
        // The nearest wall (across the tip's x axis, 2 cm thick) that leaves `q` free.
        let wall_at = |ahead: f64| Object {
            name: "wall".into(),
            shape: Shape::cuboid([0.02, 0.3, 0.3]),
            pose: Pose::from_parts(
                (start.translation.vector + start.rotation * (Vector3::x() * (ahead + 0.01)))
                    .into(),
                start.rotation,
            ),
        };
        let env = (0..60)
            .map(|cm| Environment::from_objects([wall_at(cm as f64 * 0.01)]).unwrap())
            .find(|env| Validity::new(&robot, env, 1.0 / 32.0, 0.0).is_valid(&q))
            .expect("no wall position leaves the start free");
        let branches = retreats(&robot, &env, &q);
        assert!(!branches.is_empty(), "nothing retreated");
        for state in branches.iter().flatten() {
            let ahead = moved(&robot, &q, state).x;
            assert!(
                ahead <= 2.0 * TRACK_TOLERANCE.0,
                "a state moved {ahead} m towards the wall"
            );
        }
        let last = branches.last().unwrap();
        assert_eq!(last.len(), (LENGTH / STEP).round() as usize);
        assert!(moved(&robot, &q, last.last().unwrap()).norm() >= LENGTH - 0.01);
    }
}
