//! What the checkers derive from a robot alone, built once per robot on first use
//! ([`Robot::prepared`]) and shared by every plan after, whatever its environment.

use super::batch::BatchChecker;
use super::checker::{Contact, Placement, SphereChecker};
use super::exact::ExactChecker;
use crate::robot::Robot;
use crate::world::Environment;
use std::sync::OnceLock;

/// The robot-only part of the checkers.
pub(crate) struct Prepared {
    /// Contact between links that never move apart, on the exact geometry (it blocks every
    /// configuration).
    pub fixed_self_contact: Option<Contact>,
    /// The sphere model at rest, links that never move placed.
    pub spheres: Placement,
    /// The batch checker in an empty environment; `None` when a link has more clusters than
    /// it takes.
    pub batch: Option<BatchChecker>,
}

impl Prepared {
    fn new(robot: &Robot) -> Self {
        Prepared {
            fixed_self_contact: ExactChecker::fixed_self_contact(robot),
            spheres: SphereChecker::placement(robot),
            batch: BatchChecker::for_robot(robot),
        }
    }
}

/// A robot's [`Prepared`], built on first use. A clone starts empty: a changed copy of a
/// robot (an object attached, a passive joint moved) derives its own.
#[derive(Default)]
pub(crate) struct PreparedCell(OnceLock<Box<Prepared>>);

impl PreparedCell {
    /// The robot's prepared data (`robot` must be the one holding this cell).
    pub fn get(&self, robot: &Robot) -> &Prepared {
        self.0.get_or_init(|| Box::new(Prepared::new(robot)))
    }
}

impl Clone for PreparedCell {
    fn clone(&self) -> Self {
        PreparedCell::default()
    }
}

impl std::fmt::Debug for PreparedCell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let state = if self.0.get().is_some() {
            "built"
        } else {
            "empty"
        };
        write!(f, "PreparedCell({state})")
    }
}

/// An empty environment, for the robot-only parts.
pub(crate) fn nothing() -> &'static Environment {
    static NOTHING: OnceLock<Environment> = OnceLock::new();
    NOTHING.get_or_init(Environment::new)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planning::PlannerRng;
    use rand::SeedableRng;

    /// A copy with a joint outside the group moved (the head turned towards where the arm
    /// reaches) checks as the same copy of a robot never used, not as the robot it came from.
    #[test]
    fn a_changed_copy_derives_its_own() {
        let (used, fresh) = (
            Robot::builtin("fetch").unwrap(),
            Robot::builtin("fetch").unwrap(),
        );
        let turned = [("head_pan_joint", 1.2), ("head_tilt_joint", 1.0)];
        let mut before = SphereChecker::new(&used, nothing());
        let _ = before.is_valid(used.named_state("stow").unwrap());
        let a = used.with_joint_values(turned).unwrap();
        let b = fresh.with_joint_values(turned).unwrap();
        assert!(matches!(a, std::borrow::Cow::Owned(_)));
        let (mut sut, mut oracle) = (
            SphereChecker::new(&a, nothing()),
            SphereChecker::new(&b, nothing()),
        );
        let mut rng = PlannerRng::seed_from_u64(7);
        let mut q = vec![0.0; used.dof()];
        let mut moved_matters = 0;
        for _ in 0..4000 {
            used.sample_uniform(&mut rng, &mut q);
            let verdict = sut.is_valid(&q);
            assert_eq!(verdict, oracle.is_valid(&q), "{q:?}");
            moved_matters += usize::from(verdict != before.is_valid(&q));
        }
        assert!(
            moved_matters > 0,
            "the head never met the arm: the test shows nothing"
        );
    }
}
