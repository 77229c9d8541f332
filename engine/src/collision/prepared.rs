//! What the checkers derive from a robot alone, built once per robot on first use
//! ([`Robot::prepared`]) and shared by every plan after, whatever its environment.

use super::batch::BatchChecker;
use super::checker::{Contact, Placement, SphereChecker};
use super::exact::{ExactChecker, Rest};
use crate::robot::Robot;
use crate::world::Environment;
use std::sync::{Mutex, OnceLock};

/// The robot-only part of the checkers.
pub(crate) struct Prepared {
    /// The exact checker's robot-only part.
    pub exact: Rest,
    /// Contact between links that never move apart, on the exact geometry (it blocks every
    /// configuration).
    pub fixed_self_contact: Option<Contact>,
    /// The sphere model at rest, links that never move placed.
    pub spheres: Placement,
    /// The batch checker in an empty environment.
    pub batch: BatchChecker,
    /// Working copies of the two above that finished plans gave back: the next plan takes one
    /// instead of copying the templates (with a fine sphere model they hold ~100 kB each, and
    /// the copy was a tenth of a short plan).
    spare_spheres: Spares<Placement>,
    spare_batch: Spares<BatchChecker>,
}

impl Prepared {
    fn new(robot: &Robot) -> Self {
        let exact = Rest::new(robot);
        Prepared {
            fixed_self_contact: ExactChecker::fixed_self_contact(robot, &exact),
            exact,
            spheres: SphereChecker::placement(robot),
            batch: BatchChecker::for_robot(robot),
            spare_spheres: Spares::default(),
            spare_batch: Spares::default(),
        }
    }

    /// A working copy of the sphere placement: a spare, else a copy of the template.
    pub fn take_spheres(&self) -> Placement {
        self.spare_spheres
            .take()
            .unwrap_or_else(|| self.spheres.clone())
    }

    /// A working copy of the batch checker (its environment still to be set): a spare, else
    /// a copy of the template.
    pub fn take_batch(&self) -> BatchChecker {
        self.spare_batch
            .take()
            .unwrap_or_else(|| self.batch.clone())
    }

    /// Gives back working copies taken from this robot's templates, for the next plan.
    pub fn give_back(&self, spheres: Placement, batch: Option<BatchChecker>) {
        self.spare_spheres.give(spheres);
        if let Some(b) = batch {
            self.spare_batch.give(b);
        }
    }
}

/// A few spare working copies; more than [`Spares::KEPT`] given back are dropped.
struct Spares<T>(Mutex<Vec<T>>);

impl<T> Default for Spares<T> {
    fn default() -> Self {
        Spares(Mutex::new(Vec::new()))
    }
}

impl<T> Spares<T> {
    /// As many as plans a daemon runs at once, and then some.
    const KEPT: usize = 8;

    fn take(&self) -> Option<T> {
        self.0.lock().ok()?.pop()
    }

    fn give(&self, t: T) {
        if let Ok(mut spares) = self.0.lock() {
            if spares.len() < Self::KEPT {
                spares.push(t);
            }
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

    /// A plan's working copies, given back, serve the next plan in another environment with
    /// nothing of the first: a wall that blocked a motion there is gone here, and the other
    /// way round.
    #[test]
    fn a_spare_carries_nothing_of_its_last_environment() {
        use crate::collision::shape::Shape;
        use crate::planning::validity::Validity;
        use crate::world::{Environment, Object};
        let fetch = Robot::builtin("fetch").unwrap();
        let (a, b) = (
            vec![0.2, 0.5, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0],
            vec![0.2, 0.8, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0],
        );
        let mut walled = Environment::new();
        walled
            .add(Object {
                name: "wall".into(),
                shape: Shape::Box {
                    half_extents: [0.3, 1.0, 0.8],
                },
                pose: crate::Pose::translation(0.9, 0.0, 0.8),
            })
            .unwrap();
        let empty = Environment::new();
        let reach =
            |env: &Environment| Validity::new(&fetch, env, 1.0 / 32.0, 0.0).reach_valid(&a, &b);
        let fresh = Robot::builtin("fetch").unwrap();
        let fresh_reach =
            |env: &Environment| Validity::new(&fresh, env, 1.0 / 32.0, 0.0).reach_valid(&a, &b);
        assert!(
            !fresh_reach(&walled),
            "the wall does not block the motion: the test shows nothing"
        );
        assert!(fresh_reach(&empty));
        for env in [&walled, &empty, &walled, &empty] {
            assert_eq!(reach(env), fresh_reach(env));
            assert_eq!(fetch.prepared().spare_batch.0.lock().unwrap().len(), 1);
        }
    }

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
