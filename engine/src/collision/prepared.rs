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
