//! Fuzzing the wire decoders with arbitrary headers and payloads (any bit pattern, biased to
//! the values that matter: the protocol version, the robot's DOF, 0, NaN, ±inf, huge and tiny
//! numbers). Every input must decode or be refused with a [`Rejection`], never panic; what
//! decodes must be usable (finite, within the configured caps). Cases: `EMBER_FUZZ_CASES`,
//! seed `EMBER_FUZZ_SEED` (see `tests/fixtures/fuzzing.rs`).

include!("../../../tests/fixtures/fuzzing.rs");

use super::{cloud, joints, objects, plan};
use crate::config::Config;
use ember_engine::experience::Method;
use ember_engine::robot::Robot;
use ember_engine::world::model::{ObjectChange, World};
use ember_sdk::wire::{self, CloudHeader, JointState, ObjectUpdate, PlanRequestHeader};
use fuzzing::{cases, runner};
use proptest::prelude::*;

fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        1 => any::<f64>(),
        8 => -3.0..3.0f64,
        1 =>
        prop::sample::select(vec![
            0.0,
            -0.0,
            1.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN_POSITIVE,
            1e300,
            -1e300,
            3600.0,
            1e-12,
        ]),
    ]
}

fn code(usual: u32) -> impl Strategy<Value = u32> {
    prop_oneof![6 => Just(usual), 1 => 0..6u32, 1 => any::<u32>()]
}

fn name() -> impl Strategy<Value = wire::Name> {
    prop_oneof![
        "[a-z]{1,8}".prop_map(|s| wire::name(&s)),
        any::<[u8; 32]>(),
        Just([0u8; 32]),
    ]
}

/// Runs `check` on `n` values of `strategy`, printing the count.
fn fuzz<S: Strategy>(target: &str, strategy: S, n: u32, check: impl Fn(S::Value)) {
    if let Err(e) = runner(n).run(&strategy, |v| {
        check(v);
        Ok(())
    }) {
        panic!("fuzz {target}: {e}");
    }
    eprintln!("fuzz {target}: {n} inputs, 0 crashes");
}

#[test]
fn fuzz_plan_requests() {
    let robot = Robot::builtin("fetch").unwrap();
    let config = Config::load(None).unwrap();
    let dof = robot.dof() as u32;
    let header = (
        (code(wire::PROTOCOL_VERSION), code(dof), code(0), code(1)),
        (code(0), code(0), number(), any::<u64>()),
        (
            prop::array::uniform7(number()),
            number(),
            number(),
            any::<u64>(),
        ),
    )
        .prop_map(
            |(
                (version, dof, goal_kind, goal_count),
                (method, flags, t, seed),
                (pose, pt, ot, id),
            )| {
                PlanRequestHeader {
                    version,
                    dof,
                    goal_kind,
                    goal_count,
                    method,
                    flags,
                    time_limit_s: t,
                    seed,
                    pose,
                    position_tolerance: pt,
                    orientation_tolerance: ot,
                    request_id: id,
                }
            },
        );
    let values = prop_oneof![
        1 => prop::collection::vec(number(), 0..40),
        3 => prop::collection::vec(-1.0..1.0f64, 16..=18),
    ];
    let accepted = std::cell::Cell::new(0);
    fuzz("plan request", (header, values), cases(20_000), |(h, v)| {
        if let Ok(d) = plan::decode::decode(&config, &robot, Method::Uniform, &h, &v) {
            accepted.set(accepted.get() + 1);
            assert!(d.request.start.iter().all(|x| x.is_finite()));
            assert_eq!(d.request.start.len(), robot.dof());
            assert!(d.request.params.time_limit.as_secs_f64() <= config.planner.max_time_limit_s);
        }
    });
    eprintln!(
        "  of which {} decoded into plannable requests",
        accepted.get()
    );
    assert!(
        accepted.get() > 0,
        "the generator never reaches a valid request"
    );
}

#[test]
fn fuzz_inputs() {
    let robot = Robot::builtin("fetch").unwrap();
    let config = Config::load(None).unwrap();
    let cloud = (
        code(wire::PROTOCOL_VERSION),
        any::<u32>(),
        prop::array::uniform7(number()),
        0usize..400_000,
    );
    fuzz(
        "cloud header",
        cloud,
        cases(20_000),
        |(version, count, pose, points)| {
            let h = CloudHeader {
                version,
                point_count: count,
                sensor_pose: pose,
                ..Default::default()
            };
            if let Ok(p) = cloud::decode(&h, points, config.map.max_points) {
                assert!(p.translation.vector.iter().all(|x| x.is_finite()));
            }
        },
    );
    // Object updates, decoded and applied to one world that lives through all of them (the
    // robot at rest, so attaching checks contact): any id, shape code and link, with real link
    // names and a few recurring ids among them so attach, detach and remove meet held objects.
    let tip = robot.links()[robot.tip()].name.clone();
    let link = prop_oneof![
        3 => Just([0u8; 32]),
        2 => Just(wire::name(&tip)),
        1 => name(),
    ];
    let id = prop_oneof![
        3 => prop::sample::select(vec!["a", "b"]).prop_map(wire::name),
        1 => name(),
    ];
    let object = (
        (code(wire::PROTOCOL_VERSION), code(1), id, link),
        (
            prop::array::uniform3(number()),
            prop::array::uniform7(number()),
        ),
    );
    let max_extent = config.map.max_object_extent();
    let world = std::cell::RefCell::new(World::new(&config.world_params()));
    world.borrow_mut().set_joints(&robot, robot.middle());
    let (fitted, attached) = (std::cell::Cell::new(0), std::cell::Cell::new(0));
    fuzz(
        "object update",
        object,
        cases(20_000),
        |((version, shape, id, link), (dims, pose))| {
            let u = ObjectUpdate {
                version,
                shape,
                id,
                dims,
                pose,
                link,
                ..Default::default()
            };
            let Ok(change) = objects::decode(&u, max_extent) else {
                return;
            };
            // Attaching a new shape fits spheres to it (tens to hundreds of ms): a few suffice.
            if matches!(change, ObjectChange::Attach { shape: Some(_), .. }) {
                if fitted.get() >= 30 {
                    return;
                }
                fitted.set(fitted.get() + 1);
            }
            let mut world = world.borrow_mut();
            if let ObjectChange::Upsert(o) = &change {
                assert!(o.pose.translation.vector.iter().all(|x| x.is_finite()));
                assert!(o.shape.bounding_radius().is_finite());
                if world.would_exceed(&o.name, config.limits.objects) {
                    return; // Refused before it reaches the world, as the ingest thread does.
                }
            }
            let attach = matches!(change, ObjectChange::Attach { .. });
            if world.apply(&robot, change).is_ok() && attach {
                attached.set(attached.get() + 1);
            }
            let snap = world.snapshot();
            assert_eq!(
                snap.robot(&robot).links().len(),
                robot.links().len() + snap.scene.attached.len()
            );
        },
    );
    eprintln!("  of which {} attached an object", attached.get());
    assert!(attached.get() > 0, "the generator never attaches");
    let dof = robot.dof() as u32;
    let joint = (
        code(wire::PROTOCOL_VERSION),
        code(dof),
        prop::array::uniform16(number()),
    );
    fuzz(
        "joint state",
        joint,
        cases(20_000),
        |(version, count, positions)| {
            let js = JointState {
                version,
                count,
                positions,
                ..Default::default()
            };
            if let Ok(j) = joints::decode(&js, &robot) {
                assert!(robot.validate(&j.positions).is_ok());
            }
        },
    );
}
