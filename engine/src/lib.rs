//! Ember's engine: robot models, collision checking, the world model, experience-based sampling
//! and motion planning, usable as a library without any IPC.
//!
//! Layout: [`robot`] (descriptions, kinematics, sphere models), [`collision`] (shapes, distance
//! queries, the fast sphere checker and the exact parry3d path), [`world`] (what the robot plans
//! in), [`scene`] (scenes and MoveIt interchange), [`planning`] (RRT-Connect, simplification,
//! inverse kinematics).
#![warn(missing_docs)]

pub mod collision;
pub mod experience;
pub mod planning;
pub mod problems;
pub mod robot;
pub mod scene;
pub mod trajectory;
pub mod world;

/// A pose: rotation and translation, metres, as used at every boundary of the engine.
pub type Pose = nalgebra::Isometry3<f64>;
