//! SPARK and FLAME: metric, retrieval indexes, the database contract (run against both
//! databases), files, samplers, learning, the experience folder.

use ember_engine::experience::learn::path_states;
use ember_engine::experience::{
    BoxPrimitive, Database, DbError, Experience, ExperienceParams, FlameDb, GlobalSampler,
    LocalSampler, Method, Octobox, Retrieval, SparkDb, SparkPair,
};
use ember_engine::planning::{PlannerRng, Sampler};
use ember_engine::robot::Robot;
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_engine::world::map::{MapParams, OccupancyMap};
use ember_engine::Pose;
use rand::{Rng, SeedableRng};

fn random_box(rng: &mut PlannerRng) -> BoxPrimitive {
    let q: [f64; 4] = [0, 1, 2, 3].map(|_| rng.random_range(-1.0..1.0));
    let pose = pose_from_xyz_xyzw([0, 1, 2].map(|_| rng.random_range(-1.0..1.0)), q)
        .unwrap_or(Pose::identity());
    BoxPrimitive {
        pose,
        size: [0, 1, 2].map(|_| rng.random_range(0.02..0.5)),
    }
}

fn random_pair(rng: &mut PlannerRng) -> SparkPair {
    SparkPair {
        a: random_box(rng),
        b: random_box(rng),
        names: ["a".into(), "b".into()],
    }
}

fn configs(rng: &mut PlannerRng, n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| (0..8).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect()
}

fn temp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("ember-it-{}-{name}", std::process::id()))
}

#[test]
fn pair_distance_is_a_metric() {
    let p = ExperienceParams::default();
    let mut rng = PlannerRng::seed_from_u64(1);
    for _ in 0..2000 {
        let (a, b, c) = (
            random_pair(&mut rng),
            random_pair(&mut rng),
            random_pair(&mut rng),
        );
        assert!(a.distance(&a, &p).abs() < 1e-9);
        assert!((a.distance(&b, &p) - b.distance(&a, &p)).abs() < 1e-12);
        // Up to the angle's documented approximation (2e-8 rad per box; the tree prunes with
        // a 1e-6 slack).
        assert!(a.distance(&c, &p) <= a.distance(&b, &p) + b.distance(&c, &p) + 1e-7);
    }
}

#[test]
fn metric_tree_returns_exactly_what_the_linear_scan_returns() {
    let mut rng = PlannerRng::seed_from_u64(2);
    // A small radius relative to the spread, so queries return some but not all entries.
    let mut sut = SparkDb::new(ExperienceParams {
        d_radius: 1.0,
        ..Default::default()
    });
    for _ in 0..1500 {
        let k = random_pair(&mut rng);
        sut.insert(k, configs(&mut rng, 1));
    }
    let mut hits = 0;
    for _ in 0..200 {
        let q = random_pair(&mut rng);
        let tree = sut.within(&q);
        assert_eq!(tree, sut.within_linear(&q));
        hits += tree.len();
    }
    assert!(
        hits > 0 && hits < 200 * sut.len(),
        "queries should be selective: {hits}"
    );
}

#[test]
fn scene_retrieval_matches_the_linear_scan_when_pairs_share_boxes() {
    let mut rng = PlannerRng::seed_from_u64(3);
    let mut sut = SparkDb::new(ExperienceParams {
        d_radius: 1.0,
        ..Default::default()
    });
    // Scenes of 6 boxes and all their pairs: entries share boxes, as real scenes' pairs do.
    let scene = |rng: &mut PlannerRng| {
        let boxes: Vec<_> = (0..6).map(|_| random_box(rng)).collect();
        let mut pairs = Vec::new();
        for i in 0..6 {
            for j in i + 1..6 {
                pairs.push(SparkPair {
                    a: boxes[i],
                    b: boxes[j],
                    names: [format!("o{i}"), format!("o{j}")],
                });
            }
        }
        pairs
    };
    for _ in 0..100 {
        for p in scene(&mut rng) {
            sut.insert(p, configs(&mut rng, 2));
        }
    }
    let mut found = 0;
    for _ in 0..30 {
        let q = scene(&mut rng);
        let (tree, linear) = (sut.retrieve(&q), sut.retrieve_linear(&q));
        assert_eq!(tree, linear);
        found += tree.entries;
    }
    assert!(found > 0 && found < 30 * 15 * sut.len(), "{found}");
}

#[test]
fn flame_matches_equal_masks_within_the_radius_as_the_linear_scan_does() {
    let mut rng = PlannerRng::seed_from_u64(9);
    // 0.02 m leaves: octoboxes 0.08 m apart; 0.2 m reaches 2.5 octoboxes along an axis.
    let mut sut = FlameDb::new(ExperienceParams::default(), 0.02);
    // Few masks, so equal masks meet at many positions, on both sides of zero.
    let masks = [0xffff_u64, 0xff00_ff00, u64::MAX];
    for _ in 0..3000 {
        let key = [0, 1, 2].map(|_| rng.random_range(-12..12));
        let mask = masks[rng.random_range(0..masks.len())];
        sut.insert(Octobox { key, mask }, configs(&mut rng, 1));
    }
    let mut found = 0;
    for _ in 0..300 {
        let key = [0, 1, 2].map(|_| rng.random_range(-14..14));
        let q = Octobox {
            key,
            mask: masks[rng.random_range(0..masks.len())],
        };
        let cells = sut.matches(&q);
        assert_eq!(cells, sut.matches_linear(&q), "{q:?}");
        found += cells.len();
    }
    assert!(found > 300 && found < 300 * sut.len() / 10, "{found}");

    // The authors' match: same mask and centres within 0.2 m, not only the same octobox.
    let mut one = FlameDb::new(ExperienceParams::default(), 0.02);
    let stored = Octobox {
        key: [5, 5, 5],
        mask: 0xff,
    };
    one.insert(stored, configs(&mut rng, 1));
    let at = |key: [i32; 3], mask: u64| one.retrieve(&[Octobox { key, mask }]).entries;
    assert_eq!(at([5, 5, 5], 0xff), 1);
    assert_eq!(at([7, 5, 5], 0xff), 1, "0.16 m away");
    assert_eq!(at([7, 6, 5], 0xff), 1, "0.179 m away");
    assert_eq!(at([7, 6, 6], 0xff), 1, "0.196 m away");
    assert_eq!(at([8, 5, 5], 0xff), 0, "0.24 m away");
    assert_eq!(at([7, 7, 5], 0xff), 0, "0.226 m away");
    assert_eq!(at([5, 5, 5], 0xfe), 0, "another mask");
}

#[test]
fn flame_matches_equal_the_linear_scan_at_every_reach() {
    // Radii from the same octobox only (reach 0) to several octoboxes (cells of 1, 2, 4, 8),
    // with keys on both sides of zero and far from it, and enough entries to grow the table.
    let mut rng = PlannerRng::seed_from_u64(10);
    for radius in [0.05, 0.1, 0.2, 0.3, 0.5] {
        let params = ExperienceParams {
            flame_radius: radius,
            ..Default::default()
        };
        let mut sut = FlameDb::new(params, 0.02);
        let masks = [0x1_u64, 0xf0f0, u64::MAX];
        let offset = [0, 1, 2].map(|_| rng.random_range(-100_000..100_000));
        let key = |rng: &mut PlannerRng, span: i32| {
            [0, 1, 2].map(|i| offset[i] + rng.random_range(-span..span))
        };
        for _ in 0..2000 {
            let k = key(&mut rng, 10);
            let mask = masks[rng.random_range(0..masks.len())];
            sut.insert(Octobox { key: k, mask }, configs(&mut rng, 1));
        }
        let queries: Vec<_> = (0..200)
            .map(|_| Octobox {
                key: key(&mut rng, 12),
                mask: masks[rng.random_range(0..masks.len())],
            })
            .collect();
        let mut expected = 0;
        for q in &queries {
            let linear = sut.matches_linear(q);
            assert_eq!(sut.matches(q), linear, "radius {radius}, {q:?}");
            expected += linear.len();
        }
        // One retrieval over all queries finds the same matches as the queries one by one.
        assert_eq!(sut.retrieve(&queries).entries, expected, "radius {radius}");
        assert!(expected > 0, "radius {radius}");
    }
}

#[test]
fn equal_primitives_share_an_entry() {
    let mut rng = PlannerRng::seed_from_u64(3);
    let mut sut = SparkDb::new(ExperienceParams::default());
    let k = random_pair(&mut rng);
    let swapped = SparkPair {
        a: k.b,
        b: k.a,
        names: ["b".into(), "a".into()],
    };
    sut.insert(k, configs(&mut rng, 2));
    sut.insert(swapped, configs(&mut rng, 3));
    assert_eq!(sut.len(), 1);
    assert_eq!(sut.configurations(), 5);
}

/// What the conformance tests need of a database kind: an empty database and random
/// primitives that sometimes repeat, so entries merge.
trait Kind: Database + std::fmt::Debug {
    fn empty() -> Self;
    fn primitive(rng: &mut PlannerRng) -> Self::Primitive;
    /// A primitive that matches none of [`Kind::primitive`]'s.
    fn unmatched() -> Self::Primitive;
    /// Equal primitives (SPARK pairs carry poses: compared by distance).
    fn same(a: &Self::Primitive, b: &Self::Primitive) -> bool;
}

impl Kind for SparkDb {
    fn empty() -> Self {
        // A radius small against the spread: queries return some entries, not all.
        SparkDb::new(ExperienceParams {
            d_radius: 1.0,
            ..Default::default()
        })
    }
    fn primitive(rng: &mut PlannerRng) -> SparkPair {
        random_pair(rng)
    }
    fn unmatched() -> SparkPair {
        let b = BoxPrimitive {
            pose: Pose::translation(100.0, 0.0, 0.0),
            size: [0.1; 3],
        };
        SparkPair {
            a: b,
            b,
            names: ["far".into(), "away".into()],
        }
    }
    fn same(a: &SparkPair, b: &SparkPair) -> bool {
        a.distance(b, &ExperienceParams::default()) < 1e-12
    }
}

impl Kind for FlameDb {
    fn empty() -> Self {
        FlameDb::new(ExperienceParams::default(), 0.02)
    }
    fn primitive(rng: &mut PlannerRng) -> Octobox {
        let masks = [0xffff_u64, 0xff00_ff00, u64::MAX];
        Octobox {
            key: [0, 1, 2].map(|_| rng.random_range(-12..12)),
            mask: masks[rng.random_range(0..masks.len())],
        }
    }
    fn unmatched() -> Octobox {
        Octobox {
            key: [0; 3],
            mask: 1,
        }
    }
    fn same(a: &Octobox, b: &Octobox) -> bool {
        a == b
    }
}

/// A database of `n` random entries (some primitives repeated) and its inserted primitives.
fn filled<D: Kind>(seed: u64, n: usize) -> (D, Vec<D::Primitive>) {
    let mut rng = PlannerRng::seed_from_u64(seed);
    let mut db = D::empty();
    let mut keys: Vec<D::Primitive> = Vec::new();
    for i in 0..n {
        let k = if i % 10 == 9 {
            keys[rng.random_range(0..keys.len())].clone()
        } else {
            D::primitive(&mut rng)
        };
        let c = rng.random_range(1..4);
        db.insert(k.clone(), configs(&mut rng, c));
        keys.push(k);
    }
    (db, keys)
}

/// The index retrieves exactly what the linear scan retrieves (samplers, order, counts), on
/// stored primitives and on fresh ones, alone and in scenes.
fn conformance_retrieval<D: Kind>() {
    let (db, keys) = filled::<D>(21, 1500);
    let mut rng = PlannerRng::seed_from_u64(22);
    assert!(db.len() < keys.len(), "repeated primitives share entries");
    let stored: usize = db.samplers().iter().map(LocalSampler::len).sum();
    assert_eq!(db.configurations(), stored);
    let mut some = 0;
    for t in 0..200 {
        let scene: Vec<D::Primitive> = (0..1 + t % 6)
            .map(|i| {
                if i == 0 && t % 2 == 0 {
                    keys[rng.random_range(0..keys.len())].clone()
                } else {
                    D::primitive(&mut rng)
                }
            })
            .collect();
        let (index, linear) = (db.retrieve(&scene), db.retrieve_linear(&scene));
        assert_eq!(index, linear, "{} query {t}", D::NAME);
        assert_eq!(index.query_primitives, scene.len());
        some += !index.samplers.is_empty() as usize;
        assert!(index.samplers.len() < db.len(), "{}: selective", D::NAME);
    }
    assert!(some > 50, "{}: {some} queries found something", D::NAME);
    let nothing = [D::unmatched()];
    assert_eq!(
        db.retrieve(&nothing),
        Retrieval {
            query_primitives: 1,
            ..Default::default()
        }
    );
    assert_eq!(db.retrieve_linear(&nothing), db.retrieve(&nothing));
    // A stored primitive retrieves its own sampler.
    let k = &keys[0];
    let own = &db.samplers()[db.keys().iter().position(|x| D::same(x, k)).unwrap()];
    assert!(db
        .retrieve(std::slice::from_ref(k))
        .samplers
        .iter()
        .any(|s| **s == *own));
}

/// Save and load give back the same database: entries, samplers, parameters, retrievals.
fn conformance_file_loopback<D: Kind>() {
    let (db, _) = filled::<D>(23, 300);
    let path = temp(&format!("loop-{}", D::FILE_NAME));
    db.save(&path).unwrap();
    let back = D::load(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(
        (back.len(), back.configurations()),
        (db.len(), db.configurations())
    );
    assert_eq!(back.params(), db.params());
    assert_eq!(back.samplers(), db.samplers());
    assert!(back
        .keys()
        .iter()
        .zip(db.keys())
        .all(|(a, b)| D::same(a, b)));
    let mut rng = PlannerRng::seed_from_u64(24);
    for _ in 0..50 {
        let q = [D::primitive(&mut rng), D::primitive(&mut rng)];
        assert_eq!(back.retrieve(&q), db.retrieve(&q));
    }
    // Merging into an empty database gives the same entries.
    let mut merged = D::empty();
    merged.merge(&db);
    assert_eq!(merged.samplers(), db.samplers());
}

/// Bad files are refused with an error that names what is wrong.
fn conformance_bad_files<D: Kind, Other: Kind>() {
    let (db, _) = filled::<D>(25, 100);
    let path = temp(&format!("bad-{}", D::FILE_NAME));
    db.save(&path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let load = |b: &[u8]| {
        std::fs::write(&path, b).unwrap();
        D::load(&path).unwrap_err()
    };
    let e = load(&bytes[..bytes.len() / 2]);
    assert!(matches!(e, DbError::Truncated(_)), "{e}");
    let e = load(&bytes[..10]);
    assert!(matches!(e, DbError::Truncated(_)), "{e}");
    let mut corrupt = bytes.clone();
    let mid = corrupt.len() / 2;
    corrupt[mid] ^= 0xff;
    let e = load(&corrupt);
    assert!(
        matches!(e, DbError::Checksum(_)) && e.to_string().contains("corrupt"),
        "{e}"
    );
    let e = load(b"PK\x03\x04 a zip file");
    assert!(matches!(e, DbError::NotADatabase(_)), "{e}");
    let mut future = bytes.clone();
    future[8] = 99;
    let e = load(&future);
    assert!(matches!(e, DbError::Version { found: 99, .. }), "{e}");
    // A database of the other kind.
    let (other, _) = filled::<Other>(26, 10);
    other.save(&path).unwrap();
    let e = D::load(&path).unwrap_err();
    assert!(
        matches!(e, DbError::WrongKind { .. }) && e.to_string().contains(D::NAME),
        "{e}"
    );
    let e = D::load(&temp("missing.emberdb")).unwrap_err();
    assert!(matches!(e, DbError::Io { .. }), "{e}");
    std::fs::remove_file(&path).ok();
}

#[test]
fn spark_database_conforms() {
    conformance_retrieval::<SparkDb>();
    conformance_file_loopback::<SparkDb>();
    conformance_bad_files::<SparkDb, FlameDb>();
}

#[test]
fn flame_database_conforms() {
    conformance_retrieval::<FlameDb>();
    conformance_file_loopback::<FlameDb>();
    conformance_bad_files::<FlameDb, SparkDb>();
}

#[test]
fn version_1_files_still_load() {
    // A version 1 file (parameters without `flame_radius`) loads, with its default.
    let (flame, _) = filled::<FlameDb>(27, 100);
    let fpath = temp("v1-flame.emberdb");
    flame.save(&fpath).unwrap();
    let v2 = std::fs::read(&fpath).unwrap();
    let payload = &v2[21..v2.len() - 4];
    let mut v1_payload = payload[..6 * 8].to_vec();
    v1_payload.extend_from_slice(&payload[7 * 8..]);
    let mut v1 = b"EMBEREXP".to_vec();
    v1.extend_from_slice(&1u32.to_le_bytes());
    v1.push(v2[12]);
    v1.extend_from_slice(&(v1_payload.len() as u64).to_le_bytes());
    v1.extend_from_slice(&v1_payload);
    v1.extend_from_slice(&crc32fast::hash(&v1_payload).to_le_bytes());
    std::fs::write(&fpath, &v1).unwrap();
    let old = FlameDb::load(&fpath).unwrap();
    std::fs::remove_file(&fpath).ok();
    assert_eq!(old.params(), flame.params());
    assert!(old.entries().eq(flame.entries()));
}

#[test]
fn an_experience_folder_loads_saves_and_sets_bad_files_aside() {
    let dir = temp("experience-dir");
    std::fs::remove_dir_all(&dir).ok();
    let params = ExperienceParams::default();
    // Nothing there: empty databases, nothing set aside.
    let (mut sut, aside) = Experience::load_dir(&dir, &params, 0.02).unwrap();
    assert!(sut.spark.is_empty() && sut.flame.is_empty() && aside.is_empty());
    assert_eq!(sut.default_method(), Method::Uniform);
    let (spark, _) = filled::<SparkDb>(28, 50);
    let (flame, _) = filled::<FlameDb>(29, 50);
    sut.spark.merge(&spark);
    sut.flame.merge(&flame);
    sut.save_dir(&dir).unwrap();
    assert!(!sut.is_dirty());
    let (back, aside) = Experience::load_dir(&dir, &params, 0.02).unwrap();
    assert!(aside.is_empty());
    assert_eq!(back.spark.samplers(), spark.samplers());
    assert_eq!(back.flame.samplers(), flame.samplers());
    assert_eq!(back.default_method(), Method::Spark);
    // What a save killed midway leaves behind is removed when its process is gone (not while
    // it lives: ours stays).
    let stale = dir.join(".spark.emberdb.tmp-4000000000");
    let live = dir.join(format!(".flame.emberdb.tmp-{}", std::process::id()));
    std::fs::write(&stale, b"half").unwrap();
    std::fs::write(&live, b"half").unwrap();
    Experience::load_dir(&dir, &params, 0.02).unwrap();
    assert!(!stale.exists() && live.exists());
    std::fs::remove_file(&live).unwrap();
    // A corrupt SPARK file is moved aside (kept, not overwritten); FLAME still loads.
    let [spark_file, _] = Experience::files(&dir);
    let mut bytes = std::fs::read(&spark_file).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 1;
    std::fs::write(&spark_file, &bytes).unwrap();
    let (again, aside) = Experience::load_dir(&dir, &params, 0.02).unwrap();
    assert!(again.spark.is_empty() && again.flame.len() == flame.len());
    assert_eq!(aside.len(), 1);
    assert!(matches!(aside[0].error, DbError::Checksum(_)));
    assert_eq!(std::fs::read(&aside[0].moved_to).unwrap(), bytes);
    assert!(!spark_file.exists());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sampler_matches_its_components() {
    let robot = Robot::builtin("fetch").unwrap();
    let mean = vec![0.2, 0.3, 0.1, 0.0, 0.5, 0.0, -0.4, 0.0];
    let retrieval =
        Retrieval::from_samplers(vec![LocalSampler::from_means(std::slice::from_ref(&mean))]);
    let mut sut = GlobalSampler::new(retrieval, 0.1, 0.0);
    let mut rng = PlannerRng::seed_from_u64(5);
    let n = 20000;
    let mut sum = [0.0; 8];
    let mut sq = [0.0; 8];
    let mut q = [0.0; 8];
    for _ in 0..n {
        sut.sample(&robot, &mut rng, &mut q);
        assert!(robot.validate(&q).is_ok());
        for j in 0..8 {
            sum[j] += q[j];
            sq[j] += q[j] * q[j];
        }
    }
    // Joints far from their limits: mean and spread of the component.
    for j in 1..8 {
        let m = sum[j] / n as f64;
        let sd = (sq[j] / n as f64 - m * m).sqrt();
        assert!((m - mean[j]).abs() < 0.005, "joint {j} mean {m}");
        assert!((sd - 0.1).abs() < 0.005, "joint {j} sd {sd}");
    }
    // The torso (0.1 from its lower limit 0) is clamped: samples pile up at the limit.
    assert!(sum[0] / n as f64 > 0.1);
}

#[test]
fn sampler_falls_back_to_uniform_when_nothing_is_retrieved() {
    let robot = Robot::builtin("fetch").unwrap();
    let mut sut = GlobalSampler::new(Retrieval::default(), 0.2, 0.5);
    assert_eq!(sut.local_samplers(), 0);
    let mut rng = PlannerRng::seed_from_u64(6);
    let mut q = [0.0; 8];
    // Every bounded joint's range, in ten bins: each bin gets its share (10% ± 2%).
    let n = 20000;
    let mut bins = [[0usize; 10]; 8];
    for _ in 0..n {
        sut.sample(&robot, &mut rng, &mut q);
        for (j, v) in robot.variables().iter().enumerate() {
            let (lo, hi) = (v.lower, v.upper);
            assert!((lo..=hi).contains(&q[j]), "joint {j}: {} outside", q[j]);
            let b = (((q[j] - lo) / (hi - lo)) * 10.0) as usize;
            bins[j][b.min(9)] += 1;
        }
    }
    for (j, b) in bins.iter().enumerate() {
        for (k, &c) in b.iter().enumerate() {
            let share = c as f64 / n as f64;
            assert!((share - 0.1).abs() < 0.02, "joint {j} bin {k}: {share}");
        }
    }
}

#[test]
fn lambda_mixes_uniform_and_biased_samples() {
    let robot = Robot::builtin("fetch").unwrap();
    let mean = vec![0.2, 0.3, 0.1, 0.0, 0.5, 0.0, -0.4, 0.0];
    let retrieval =
        Retrieval::from_samplers(vec![LocalSampler::from_means(std::slice::from_ref(&mean))]);
    let mut sut = GlobalSampler::new(retrieval, 0.01, 0.5);
    let mut rng = PlannerRng::seed_from_u64(7);
    let mut q = [0.0; 8];
    let n = 10000;
    let near = (0..n)
        .filter(|_| {
            sut.sample(&robot, &mut rng, &mut q);
            (q[4] - 0.5).abs() < 0.05
        })
        .count();
    let share = near as f64 / n as f64;
    assert!(
        (share - 0.5).abs() < 0.03,
        "share of biased samples {share}"
    );
}

#[test]
fn learning_from_a_path_fills_both_databases() {
    let robot = Robot::builtin("fetch").unwrap();
    let scene =
        ember_engine::scene::Scene::load(crate::fixtures().join("moveit/scene.yaml")).unwrap();
    // A path ending with the hand right behind the can on the table (found by IK).
    let env = scene.environment().unwrap();
    let mut checker = ember_engine::collision::SphereChecker::new(&robot, &env);
    let goal = ember_engine::planning::PoseGoal {
        link: None,
        pose: Pose::translation(0.66, 0.1, 0.86),
        position_tolerance: 0.005,
        orientation_tolerance: 0.05,
    };
    let mut rng = PlannerRng::seed_from_u64(8);
    let ik =
        ember_engine::planning::ik::solve(&mut checker, &goal, None, &Default::default(), &mut rng)
            .unwrap();
    let path = vec![robot.named_state("tuck").unwrap().to_vec(), ik[0].clone()];
    let mut map = OccupancyMap::new(MapParams::default());
    // Occupied voxels along the table top.
    let top: Vec<[f32; 3]> = (0..40)
        .flat_map(|i| (0..40).map(move |j| [0.7 + 0.02 * i as f32, -0.4 + 0.02 * j as f32, 0.72]))
        .collect();
    map.insert_cloud(&top, &Pose::identity(), None);
    let mut sut = Experience::new(ExperienceParams::default(), 0.02);
    let boxes = ember_engine::experience::flame::octoboxes(&map);
    let learned = sut.learn(&robot, &scene, Some((&map, &boxes)), &path, Some(0.1));
    let (spark, flame) = (&sut.spark, &sut.flame);
    assert!(learned.spark_primitives >= 2, "{learned:?}");
    assert!(
        learned.spark_entries >= 1 && !spark.is_empty(),
        "{learned:?}"
    );
    assert!(
        learned.flame_entries >= 1 && !flame.is_empty(),
        "{learned:?}"
    );
    // Everything stored is a configuration of the interpolated path, which ends at the IK goal.
    let states = path_states(&robot, &path, Some(0.1));
    for (_, v) in spark.entries() {
        assert!(v.means().all(|q| states.iter().any(|s| s == q)));
    }
    // The same scene retrieves what was learned.
    let pairs = ember_engine::experience::spark::spark_pairs(&scene, spark.params());
    let boxes = ember_engine::experience::flame::octoboxes(&map);
    let r = spark.retrieve(&pairs);
    assert_eq!(r.samplers.len(), spark.len());
    let r = flame.retrieve(&boxes);
    assert_eq!(r.samplers.len(), flame.len());
    // The experience hands out samplers over what each method retrieves.
    assert_eq!(
        sut.sampler_for(Method::Spark, &pairs, &boxes)
            .local_samplers(),
        spark.len()
    );
    assert_eq!(
        sut.sampler_for(Method::Flame, &pairs, &boxes)
            .local_samplers(),
        flame.len()
    );
    assert_eq!(
        sut.sampler_for(Method::Uniform, &pairs, &boxes)
            .local_samplers(),
        0
    );
}
