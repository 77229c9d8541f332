//! The nominal scenes and variations of the problem sets (after MotionBenchMaker's Fetch
//! configurations: small shelf, tall shelf, box and table pick).
//!
//! Every scene is given in a local frame placed in front of the robot; the "world" variation
//! moves everything but the floor as one body (translation, then yaw about the robot base),
//! object variations shift single objects in their own frame. Positions uniform in ±bound (the
//! intended MotionBenchMaker semantics; its shipped code samples Gaussians by mistake).

use crate::collision::Shape;
use crate::Pose;
use nalgebra::{Translation3, UnitQuaternion};

/// Uniform variation bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variation {
    /// ± bound on x, y, z, metres.
    pub position: [f64; 3],
    /// ± bound on yaw about z, radians.
    pub yaw: f64,
}

/// A dataset: nominal scene, variations, start and goal definition.
#[derive(Debug, Clone)]
pub struct DatasetSpec {
    /// Name, e.g. `shelf_zero`.
    pub name: &'static str,
    /// Objects in the robot base frame before variation: (name, shape, pose).
    pub objects: Vec<(String, Shape, Pose)>,
    /// Names that the world variation does not move (the floor).
    pub fixed: Vec<String>,
    /// Variation of everything but `fixed`, about the robot base.
    pub world: Variation,
    /// Per-object variations: (object names, bounds in the object's frame).
    pub object_variations: Vec<(Vec<String>, Variation)>,
    /// Objects that can be the target of a pick.
    pub targets: Vec<String>,
    /// Goal pose of the tip link in the target object's frame.
    pub goal_offset: Pose,
    /// Tolerances sampled around the goal: position (m) and orientation (rad), per axis.
    pub goal_tolerance: (f64, f64),
    /// Named robot state to start from.
    pub start_state: &'static str,
    /// Place task: where the first target goes (nominal pose before the world variation, and
    /// its variation in its own frame); `None` when the dataset has no place task.
    pub place: Option<(Pose, Variation)>,
}

fn obj(name: &str, shape: Shape, x: f64, y: f64, z: f64) -> (String, Shape, Pose) {
    (name.to_string(), shape, Pose::translation(x, y, z))
}

fn cuboid(sx: f64, sy: f64, sz: f64) -> Shape {
    Shape::cuboid([sx, sy, sz])
}

const CAN: Shape = Shape::Cylinder {
    radius: 0.035,
    half_length: 0.06,
};

fn floor() -> (String, Shape, Pose) {
    obj("floor", cuboid(4.0, 4.0, 0.02), 0.0, 0.0, -0.011)
}

/// A shelf of inner width 1.0 and depth 0.4 whose boards' top faces are at `boards` (m),
/// front edge at `x0`, with three cans on each board from index `cans_from` up (the last board
/// is the top). Returns the number of cans.
fn shelf(x0: f64, boards: &[f64], cans_from: usize, out: &mut Vec<(String, Shape, Pose)>) -> usize {
    let top = boards.last().copied().unwrap_or(1.0) + 0.04;
    let cx = x0 + 0.2;
    for (i, b) in boards.iter().enumerate() {
        out.push(obj(
            &format!("board{i}"),
            cuboid(0.4, 1.0, 0.04),
            cx,
            0.0,
            b - 0.02,
        ));
    }
    out.push(obj(
        "side_left",
        cuboid(0.4, 0.04, top),
        cx,
        0.52,
        top / 2.0,
    ));
    out.push(obj(
        "side_right",
        cuboid(0.4, 0.04, top),
        cx,
        -0.52,
        top / 2.0,
    ));
    out.push(obj(
        "back",
        cuboid(0.04, 1.08, top),
        x0 + 0.42,
        0.0,
        top / 2.0,
    ));
    let mut cans = 0;
    for b in &boards[cans_from..boards.len() - 1] {
        for y in [0.25, 0.0, -0.25] {
            cans += 1;
            out.push(obj(&format!("Can{cans}"), CAN, x0 + 0.15, y, b + 0.06));
        }
    }
    cans
}

fn cans(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("Can{i}")).collect()
}

/// Every dataset the generator knows, by name.
pub fn dataset(name: &str) -> Option<DatasetSpec> {
    let front = Pose::translation(-0.2, 0.0, 0.05);
    let top_down = Pose::from_parts(
        Translation3::new(0.0, 0.0, 0.25),
        UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
    );
    let small = |world: Variation, name: &'static str| {
        let mut objects = vec![floor()];
        // One compartment between boards at 0.64 m and 1.02 m, above an empty lower shelf.
        let n = shelf(0.85, &[0.30, 0.64, 1.02], 1, &mut objects);
        DatasetSpec {
            name,
            objects,
            fixed: vec!["floor".into()],
            world,
            object_variations: vec![(
                cans(n),
                Variation {
                    position: [0.0, 0.45, 0.0],
                    yaw: 0.0,
                },
            )],
            targets: vec!["Can1".into()],
            goal_offset: front,
            goal_tolerance: (0.01, 0.01),
            start_state: "tuck",
            // Toward the back of the empty lower compartment.
            place: Some((
                Pose::translation(1.10, 0.0, 0.36),
                Variation {
                    position: [0.0, 0.3, 0.0],
                    yaw: 0.0,
                },
            )),
        }
    };
    let spec = match name {
        "shelf_zero" => small(
            Variation {
                position: [0.1, 0.1, 0.0],
                yaw: 0.0,
            },
            "shelf_zero",
        ),
        "shelf_height" => small(
            Variation {
                position: [0.1, 0.1, 0.4],
                yaw: 0.0,
            },
            "shelf_height",
        ),
        "shelf_height_rot" => small(
            Variation {
                position: [0.1, 0.1, 0.4],
                yaw: 1.57,
            },
            "shelf_height_rot",
        ),
        "shelf_tall" => {
            let mut objects = vec![floor()];
            let n = shelf(0.85, &[0.36, 0.72, 1.08, 1.44], 0, &mut objects);
            DatasetSpec {
                name: "shelf_tall",
                objects,
                fixed: vec!["floor".into()],
                world: Variation {
                    position: [0.1, 0.1, 0.0],
                    yaw: 1.57,
                },
                object_variations: vec![(
                    cans(n),
                    Variation {
                        position: [0.0, 0.45, 0.0],
                        yaw: 0.0,
                    },
                )],
                targets: vec!["Can1".into(), "Can4".into(), "Can7".into()],
                goal_offset: front,
                goal_tolerance: (0.01, 0.01),
                start_state: "tuck",
                place: None,
            }
        }
        "table_pick" => {
            let mut objects = vec![floor()];
            objects.push(obj("table_top", cuboid(0.8, 1.2, 0.04), 1.1, 0.0, 0.70));
            for (i, (dx, dy)) in [(-0.35, -0.55), (-0.35, 0.55), (0.35, -0.55), (0.35, 0.55)]
                .iter()
                .enumerate()
            {
                objects.push(obj(
                    &format!("leg{i}"),
                    cuboid(0.04, 0.04, 0.68),
                    1.1 + dx,
                    *dy,
                    0.34,
                ));
            }
            objects.push(obj("Can1", CAN, 0.85, 0.0, 0.78));
            for (i, (x, y)) in [
                (1.1, 0.3),
                (1.1, -0.3),
                (1.3, 0.0),
                (0.95, 0.4),
                (0.95, -0.4),
            ]
            .iter()
            .enumerate()
            {
                objects.push(obj(
                    &format!("Object{}", i + 1),
                    cuboid(0.08, 0.08, 0.16),
                    *x,
                    *y,
                    0.80,
                ));
            }
            DatasetSpec {
                name: "table_pick",
                objects,
                fixed: vec!["floor".into()],
                world: Variation {
                    position: [0.1, 0.1, 0.1],
                    yaw: 1.57,
                },
                object_variations: vec![
                    (
                        vec!["Can1".into()],
                        Variation {
                            position: [0.05, 0.05, 0.0],
                            yaw: 0.0,
                        },
                    ),
                    (
                        (1..=5).map(|i| format!("Object{i}")).collect(),
                        Variation {
                            position: [0.1, 0.1, 0.0],
                            yaw: 1.57,
                        },
                    ),
                ],
                targets: vec!["Can1".into()],
                goal_offset: Pose::translation(-0.2, 0.0, 0.025),
                goal_tolerance: (0.001, 0.003),
                start_state: "tuck",
                // The free middle of the table.
                place: Some((
                    Pose::translation(1.1, 0.0, 0.78),
                    Variation {
                        position: [0.05, 0.05, 0.0],
                        yaw: 0.0,
                    },
                )),
            }
        }
        "box" => {
            let mut objects = vec![floor()];
            objects.push(obj("table_top", cuboid(0.6, 0.8, 0.04), 0.9, 0.0, 0.60));
            objects.push(obj("box_bottom", cuboid(0.4, 0.5, 0.02), 0.9, 0.0, 0.63));
            objects.push(obj("box_front", cuboid(0.02, 0.5, 0.2), 0.71, 0.0, 0.74));
            objects.push(obj("box_back", cuboid(0.02, 0.5, 0.2), 1.09, 0.0, 0.74));
            objects.push(obj("box_left", cuboid(0.4, 0.02, 0.2), 0.9, 0.25, 0.74));
            objects.push(obj("box_right", cuboid(0.4, 0.02, 0.2), 0.9, -0.25, 0.74));
            objects.push(obj("Can1", CAN, 0.9, 0.0, 0.70));
            DatasetSpec {
                name: "box",
                objects,
                fixed: vec!["floor".into()],
                world: Variation {
                    position: [0.1, 0.1, 0.1],
                    yaw: 1.57,
                },
                object_variations: vec![(
                    vec!["Can1".into()],
                    Variation {
                        position: [0.0, 0.15, 0.0],
                        yaw: 0.0,
                    },
                )],
                targets: vec!["Can1".into()],
                goal_offset: top_down,
                goal_tolerance: (0.01, 0.01),
                start_state: "tuck",
                place: None,
            }
        }
        _ => return None,
    };
    Some(spec)
}

/// Names of all datasets.
pub const DATASETS: &[&str] = &[
    "shelf_zero",
    "shelf_height",
    "shelf_height_rot",
    "shelf_tall",
    "table_pick",
    "box",
];
