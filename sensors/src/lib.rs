//! Ember's sensor sources. One file per source:
//!
//! - [`depth_camera`]: a simulated pinhole depth camera ray cast against a scene, with depth noise
//!   and dropout, giving clouds in the sensor's optical frame plus the sensor pose.
//! - [`sensed_map`]: a map of a scene from a few simulated views.
#![warn(missing_docs)]

pub mod depth_camera;
pub mod sensed_map;

pub use depth_camera::{look_at, CameraModel, DepthCamera, DepthFrame, NoiseModel};
pub use sensed_map::{quarter_vga, sensed_map};
