//! Joint velocity, acceleration and jerk limits: from the URDF's `<limit velocity>`, then a
//! robot file's `[joint_limits]` section or a MoveIt `joint_limits.yaml` (the same keys), in
//! that order; later sources override earlier ones joint by joint.
//!
//! ```yaml
//! joint_limits:
//!   shoulder_pan_joint:
//!     has_velocity_limits: true
//!     max_velocity: 1.256
//!     has_acceleration_limits: true
//!     max_acceleration: 1.5
//! ```
//!
//! A key with its `has_*_limits` flag `false` is ignored (MoveIt's meaning: "no override");
//! without the flag a given value counts. Position overrides (`max_position`, ...) are not
//! applied: the URDF's position limits stand.

use serde::Deserialize;
use std::collections::BTreeMap;

/// The dynamic limits of one planning-group variable (`None`: not given).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct JointLimits {
    /// Largest speed, rad/s or m/s.
    pub velocity: Option<f64>,
    /// Largest acceleration, rad/s² or m/s².
    pub acceleration: Option<f64>,
    /// Largest jerk, rad/s³ or m/s³ (read and reported; the parameterisation is
    /// acceleration-limited).
    pub jerk: Option<f64>,
}

/// One joint's entry in a MoveIt `joint_limits.yaml` or a robot file's `[joint_limits]`.
#[derive(Debug, Clone, Default, Deserialize)]
pub struct LimitEntry {
    has_velocity_limits: Option<bool>,
    max_velocity: Option<f64>,
    has_acceleration_limits: Option<bool>,
    max_acceleration: Option<f64>,
    has_jerk_limits: Option<bool>,
    max_jerk: Option<f64>,
    // Read so MoveIt files load; the URDF's position limits stand.
    #[allow(dead_code)]
    has_position_limits: Option<bool>,
    #[allow(dead_code)]
    min_position: Option<f64>,
    #[allow(dead_code)]
    max_position: Option<f64>,
}

/// A MoveIt `joint_limits.yaml`.
#[derive(Debug, Clone, Deserialize)]
pub struct LimitsFile {
    /// Entries by joint name.
    pub joint_limits: BTreeMap<String, LimitEntry>,
}

impl LimitsFile {
    /// Parses the YAML text of a MoveIt `joint_limits.yaml`.
    pub fn parse(text: &str) -> Result<Self, String> {
        serde_yaml_ng::from_str(text).map_err(|e| e.to_string())
    }
}

impl JointLimits {
    /// These limits with `entry`'s given values in place of the current ones.
    pub fn overridden_by(self, entry: &LimitEntry) -> Self {
        let pick = |has: Option<bool>, value: Option<f64>, old: Option<f64>| match has {
            Some(false) => old,
            _ => value.or(old),
        };
        JointLimits {
            velocity: pick(entry.has_velocity_limits, entry.max_velocity, self.velocity),
            acceleration: pick(
                entry.has_acceleration_limits,
                entry.max_acceleration,
                self.acceleration,
            ),
            jerk: pick(entry.has_jerk_limits, entry.max_jerk, self.jerk),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moveit_flags_decide_which_values_count() {
        let file = LimitsFile::parse(
            "joint_limits:\n  a:\n    has_velocity_limits: true\n    max_velocity: 1.5\n    \
             has_acceleration_limits: false\n    max_acceleration: 0\n  b:\n    max_acceleration: 2\n",
        )
        .unwrap();
        let urdf = JointLimits {
            velocity: Some(1.0),
            ..Default::default()
        };
        let a = urdf.overridden_by(&file.joint_limits["a"]);
        assert_eq!((a.velocity, a.acceleration), (Some(1.5), None));
        let b = urdf.overridden_by(&file.joint_limits["b"]);
        assert_eq!((b.velocity, b.acceleration), (Some(1.0), Some(2.0)));
    }
}
