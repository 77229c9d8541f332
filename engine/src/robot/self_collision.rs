//! Which link pairs need no self-collision check, computed the way MoveIt's setup assistant
//! does when no SRDF says: pairs that are **Adjacent** (joined by a joint, looking through
//! links without geometry), in contact at the **Default** state, in contact in at least 95% of
//! random configurations (**Always**), or in none of them (**Never**). Contacts are decided on
//! the exact geometry. The result is cached by content hash next to the sphere cache, and
//! `ember robot check --write-srdf` saves it as `disable_collisions`.

use super::spheres::cache::SphereCache;
use super::{Geometry, Robot};
use crate::collision::exact::links_touch;
use crate::Pose;
use rand::{Rng, SeedableRng};
use sha2::{Digest, Sha256};

/// Random configurations sampled (MoveIt's default).
pub const DEFAULT_SAMPLES: usize = 10_000;
/// Share of samples in contact above which a pair is "Always" in collision.
const ALWAYS: f64 = 0.95;

/// Link pairs (names) not to check, with MoveIt's reason: `Adjacent`, `Default`, `Always` or
/// `Never`. Deterministic for a given robot and sample count.
pub fn skipped_pairs(
    robot: &Robot,
    samples: usize,
    cache: &SphereCache,
) -> Vec<(String, String, String)> {
    let file = cache.dir().map(|d| {
        d.join("pairs-v1")
            .join(format!("{}.txt", key(robot, samples)))
    });
    if let Some(text) = file.as_ref().and_then(|f| std::fs::read_to_string(f).ok()) {
        let parsed: Vec<(String, String, String)> = text
            .lines()
            .filter_map(|l| {
                let mut it = l.split('\t');
                Some((
                    it.next()?.to_string(),
                    it.next()?.to_string(),
                    it.next()?.to_string(),
                ))
            })
            .collect();
        if parsed
            .iter()
            .all(|(a, b, _)| robot.link_index(a).is_some() && robot.link_index(b).is_some())
        {
            return parsed;
        }
    }
    let out = compute(robot, samples);
    if let Some(f) = &file {
        let text: String = out
            .iter()
            .map(|(a, b, r)| format!("{a}\t{b}\t{r}\n"))
            .collect();
        let written = f
            .parent()
            .map(std::fs::create_dir_all)
            .unwrap_or(Ok(()))
            .and_then(|_| std::fs::write(f, text));
        if let Err(e) = written {
            tracing::warn!("self-collision cache {} not written: {e}", f.display());
        }
    }
    out
}

fn compute(robot: &Robot, samples: usize) -> Vec<(String, String, String)> {
    let links = robot.links();
    let with_geometry: Vec<usize> = (0..links.len())
        .filter(|&i| !links[i].collision.is_empty())
        .collect();
    let mut reason: Vec<Vec<Option<&'static str>>> = vec![vec![None; links.len()]; links.len()];
    // Adjacent: nearest ancestors with geometry.
    for &l in &with_geometry {
        let mut above = robot.ancestry(l).skip(1);
        if let Some(i) = above.find(|&i| !links[i].collision.is_empty()) {
            reason[l.min(i)][l.max(i)] = Some("Adjacent");
        }
    }
    let pairs: Vec<(usize, usize)> = with_geometry
        .iter()
        .enumerate()
        .flat_map(|(k, &a)| with_geometry[k + 1..].iter().map(move |&b| (a, b)))
        .filter(|&(a, b)| reason[a][b].is_none())
        .collect();
    let model = robot.exact_model();
    let mut poses = vec![Pose::identity(); links.len()];
    let default: Vec<f64> = robot
        .variables()
        .iter()
        .map(|v| 0.0f64.clamp(v.lower, v.upper))
        .collect();
    robot.forward_kinematics(&default, &mut poses);
    for &(a, b) in &pairs {
        if links_touch(model, &poses, a, b) {
            reason[a][b] = Some("Default");
        }
    }
    let open: Vec<(usize, usize)> = pairs
        .into_iter()
        .filter(|&(a, b)| reason[a][b].is_none())
        .collect();
    let mut hits = vec![0usize; open.len()];
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(0x5e1f);
    let mut q = vec![0.0; robot.dof()];
    for _ in 0..samples {
        for (v, x) in robot.variables().iter().zip(q.iter_mut()) {
            *x = rng.random_range(v.lower..=v.upper);
        }
        robot.forward_kinematics(&q, &mut poses);
        for (k, &(a, b)) in open.iter().enumerate() {
            if links_touch(model, &poses, a, b) {
                hits[k] += 1;
            }
        }
    }
    for (k, &(a, b)) in open.iter().enumerate() {
        if hits[k] == 0 {
            reason[a][b] = Some("Never");
        } else if hits[k] as f64 >= ALWAYS * samples as f64 {
            reason[a][b] = Some("Always");
        }
    }
    let mut out = Vec::new();
    for &a in &with_geometry {
        for &b in &with_geometry {
            if a < b {
                if let Some(r) = reason[a][b] {
                    out.push((links[a].name.clone(), links[b].name.clone(), r.to_string()));
                }
            }
        }
    }
    out
}

/// Every pair of links with geometry except `skipped` (link indices, smaller first).
pub fn pairs_except(robot: &Robot, skipped: &[(String, String, String)]) -> Vec<(usize, usize)> {
    let links = robot.links();
    let skip: std::collections::HashSet<(usize, usize)> = skipped
        .iter()
        .filter_map(|(a, b, _)| {
            let (a, b) = (robot.link_index(a)?, robot.link_index(b)?);
            Some((a.min(b), a.max(b)))
        })
        .collect();
    let mut out = Vec::new();
    for a in 0..links.len() {
        for b in a + 1..links.len() {
            if !links[a].collision.is_empty()
                && !links[b].collision.is_empty()
                && !skip.contains(&(a, b))
            {
                out.push((a, b));
            }
        }
    }
    out
}

/// Content key: kinematics, limits and geometry of every link, and the sample count.
fn key(robot: &Robot, samples: usize) -> String {
    let mut h = Sha256::new();
    h.update(b"ember-pairs-v1");
    h.update((samples as u64).to_le_bytes());
    for v in robot.variables() {
        h.update(v.name.as_bytes());
        h.update(v.lower.to_le_bytes());
        h.update(v.upper.to_le_bytes());
    }
    for l in robot.links() {
        h.update(l.name.as_bytes());
        h.update(format!("{:?}{:?}{:?}", l.parent, l.origin, l.motion).as_bytes());
        for ls in &l.collision {
            h.update(format!("{:?}", ls.origin).as_bytes());
            match &ls.geometry {
                Geometry::Primitive(s) => h.update(format!("{s:?}").as_bytes()),
                Geometry::Convex(hull) => {
                    for p in &hull.points {
                        for v in p {
                            h.update(v.to_le_bytes());
                        }
                    }
                }
            }
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}
