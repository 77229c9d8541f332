//! Fuzzing the wire decoders with arbitrary headers and payloads (any bit pattern, biased to
//! the values that matter: the protocol version, the robot's DOF, 0, NaN, ±inf, huge and tiny
//! numbers). Every input must decode or be refused with a [`Rejection`], never panic; what
//! decodes must be usable (finite, within the configured caps). Cases: `EMBER_FUZZ_CASES`,
//! seed `EMBER_FUZZ_SEED` (see `tests/fixtures/fuzzing.rs`).

include!("../../../tests/fixtures/fuzzing.rs");

use super::objects::ObjectInput;
use super::{cloud, joints, objects, plan};
use crate::config::Config;
use ember_engine::experience::Method;
use ember_engine::robot::Robot;
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
    let object = (
        (code(wire::PROTOCOL_VERSION), code(1), name()),
        (
            prop::array::uniform3(number()),
            prop::array::uniform7(number()),
        ),
    );
    let max_extent = config.map.max_object_extent();
    fuzz(
        "object update",
        object,
        cases(20_000),
        |((version, shape, id), (dims, pose))| {
            let u = ObjectUpdate {
                version,
                shape,
                id,
                dims,
                pose,
                ..Default::default()
            };
            if let Ok(ObjectInput::Upsert(o)) = objects::decode(&u, max_extent) {
                assert!(o.pose.translation.vector.iter().all(|x| x.is_finite()));
                assert!(o.shape.bounding_radius().is_finite());
            }
        },
    );
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
