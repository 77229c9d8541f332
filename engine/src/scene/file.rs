//! Ember's own scene file: YAML, one entry per object, shapes named as in URDF.
//!
//! ```yaml
//! name: shelf
//! objects:
//!   - name: Can1
//!     shape: {type: cylinder, radius: 0.03, length: 0.12}   # along local z
//!     position: [0.9, 0.1, 0.68]
//!     orientation: [0, 0, 0, 1]                            # x, y, z, w
//!   - name: board
//!     shape: {type: box, size: [0.4, 1.0, 0.04]}
//!     position: [1.0, 0, 0.6]
//! attached:                                                # optional: objects the robot holds
//!   - link: wrist_roll_link
//!     object:                                              # posed in the link's frame
//!       name: held_Can2
//!       shape: {type: cylinder, radius: 0.035, length: 0.12}
//!       position: [0.2, 0, -0.05]
//! ```

use super::{pose_from_xyz_xyzw, pose_to_xyz_xyzw, read_text, write_text, Scene, SceneError};
use crate::collision::Shape;
use crate::world::Object;
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    name: String,
    #[serde(default)]
    objects: Vec<ObjectEntry>,
    /// Objects the robot holds, posed in the named link's frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    attached: Vec<AttachedEntry>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AttachedEntry {
    link: String,
    object: ObjectEntry,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectEntry {
    name: String,
    shape: ShapeEntry,
    position: [f64; 3],
    #[serde(default = "identity_xyzw")]
    orientation: [f64; 4],
}

impl ObjectEntry {
    fn of(o: &Object) -> Self {
        let (position, orientation) = pose_to_xyz_xyzw(&o.pose);
        ObjectEntry {
            name: o.name.clone(),
            shape: (&o.shape).into(),
            position,
            orientation,
        }
    }

    /// The object, or an error naming `field` (e.g. `objects[2]`) in `origin`.
    fn into_object(self, origin: &str, field: &str) -> Result<Object, SceneError> {
        let err = |f: &str, message: String| SceneError::Field {
            path: origin.to_string(),
            field: format!("{field}.{f}"),
            message,
        };
        let pose = pose_from_xyz_xyzw(self.position, self.orientation).ok_or_else(|| {
            err(
                "orientation",
                "pose is not finite or the quaternion is zero".into(),
            )
        })?;
        let shape: Shape = self.shape.into();
        if !shape.is_valid() {
            return Err(err(
                "shape",
                format!("dimensions must be positive and finite, got {shape:?}"),
            ));
        }
        Ok(Object {
            name: self.name,
            shape,
            pose,
        })
    }
}

fn identity_xyzw() -> [f64; 4] {
    [0.0, 0.0, 0.0, 1.0]
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
enum ShapeEntry {
    Box { size: [f64; 3] },
    Sphere { radius: f64 },
    Cylinder { radius: f64, length: f64 },
    Capsule { radius: f64, length: f64 },
}

impl From<ShapeEntry> for Shape {
    fn from(s: ShapeEntry) -> Shape {
        match s {
            ShapeEntry::Box { size } => Shape::cuboid(size),
            ShapeEntry::Sphere { radius } => Shape::Sphere { radius },
            ShapeEntry::Cylinder { radius, length } => Shape::Cylinder {
                radius,
                half_length: length / 2.0,
            },
            ShapeEntry::Capsule { radius, length } => Shape::Capsule {
                radius,
                half_length: length / 2.0,
            },
        }
    }
}

impl From<&Shape> for ShapeEntry {
    fn from(s: &Shape) -> ShapeEntry {
        match *s {
            Shape::Box { half_extents: h } => ShapeEntry::Box {
                size: [2.0 * h[0], 2.0 * h[1], 2.0 * h[2]],
            },
            Shape::Sphere { radius } => ShapeEntry::Sphere { radius },
            Shape::Cylinder {
                radius,
                half_length,
            } => ShapeEntry::Cylinder {
                radius,
                length: 2.0 * half_length,
            },
            Shape::Capsule {
                radius,
                half_length,
            } => ShapeEntry::Capsule {
                radius,
                length: 2.0 * half_length,
            },
        }
    }
}

impl Scene {
    /// Parses Ember's scene YAML; `origin` names the input in errors.
    pub fn from_yaml(text: &str, origin: &str) -> Result<Scene, SceneError> {
        let file: SceneFile = serde_yaml_ng::from_str(text).map_err(|e| SceneError::Syntax {
            path: origin.to_string(),
            message: e.to_string(),
        })?;
        let mut scene = Scene {
            name: file.name,
            ..Default::default()
        };
        for (i, o) in file.objects.into_iter().enumerate() {
            let object = o.into_object(origin, &format!("objects[{i}]"))?;
            if scene.objects.iter().any(|x| x.name == object.name) {
                return Err(SceneError::Field {
                    path: origin.to_string(),
                    field: format!("objects[{i}].name"),
                    message: format!("duplicate object name '{}'", object.name),
                });
            }
            scene.objects.push(object);
        }
        for (i, a) in file.attached.into_iter().enumerate() {
            let object = a.object.into_object(origin, &format!("attached[{i}]"))?;
            scene.attached.push(super::AttachedObject {
                link: a.link,
                object,
            });
        }
        Ok(scene)
    }

    fn to_file(&self) -> SceneFile {
        SceneFile {
            name: self.name.clone(),
            objects: self.objects.iter().map(ObjectEntry::of).collect(),
            attached: self
                .attached
                .iter()
                .map(|a| AttachedEntry {
                    link: a.link.clone(),
                    object: ObjectEntry::of(&a.object),
                })
                .collect(),
        }
    }

    /// Ember's scene YAML for this scene.
    pub fn to_yaml(&self) -> String {
        serde_yaml_ng::to_string(&self.to_file()).expect("scene serialises")
    }

    /// The same document as [`Scene::to_yaml`], as compact JSON (what the daemon publishes).
    pub fn to_json(&self) -> String {
        serde_json::to_string(&self.to_file()).expect("scene serialises")
    }

    /// Reads a scene file: Ember's format, or a MoveIt `PlanningScene` (recognised by its
    /// `world` key).
    pub fn load(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
        let path = path.as_ref();
        let text = read_text(path)?;
        let origin = path.display().to_string();
        if super::moveit::looks_like_planning_scene(&text) {
            super::moveit::scene_from_yaml(&text, &origin)
        } else {
            Scene::from_yaml(&text, &origin)
        }
    }

    /// Writes Ember's scene YAML.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), SceneError> {
        write_text(path.as_ref(), &self.to_yaml())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_file_round_trips() {
        let text = "name: t\nobjects:\n  - name: a\n    shape: {type: cylinder, radius: 0.03, length: 0.12}\n    position: [1, 2, 3]\n    orientation: [0, 0, 0.7071068, 0.7071068]\n  - name: b\n    shape: {type: box, size: [1, 2, 3]}\n    position: [0, 0, 0]\n";
        let sut = Scene::from_yaml(text, "t.yaml").unwrap();
        let again = Scene::from_yaml(&sut.to_yaml(), "again").unwrap();
        assert_eq!(sut.objects.len(), 2);
        for (a, b) in sut.objects.iter().zip(&again.objects) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.shape, b.shape);
            assert!((a.pose.translation.vector - b.pose.translation.vector).norm() < 1e-12);
            assert!(a.pose.rotation.angle_to(&b.pose.rotation) < 1e-9);
        }
    }

    #[test]
    fn bad_dimension_names_the_object() {
        let text = "objects:\n  - name: a\n    shape: {type: sphere, radius: -1}\n    position: [0, 0, 0]\n";
        let err = Scene::from_yaml(text, "s.yaml").unwrap_err();
        assert!(err.to_string().contains("objects[0].shape"), "{err}");
    }
}
