//! Ember's sensor sources. One file per source:
//!
//! - [`depth_camera`]: a simulated pinhole depth camera ray cast against a scene, with depth noise
//!   and dropout, giving clouds in the sensor's optical frame plus the sensor pose.
#![warn(missing_docs)]

pub mod depth_camera;

pub use depth_camera::{look_at, CameraModel, DepthCamera, DepthFrame, NoiseModel};
