//! `ember robot check` and `ember robot primitives`: what Ember made of a robot description.

mod picture;

use crate::cli::{RobotCheckArgs, RobotCommand, RobotPrimitivesArgs};
use ember_engine::collision::Shape;
use ember_engine::robot::spheres::{compare, measure, FitQuality};
use ember_engine::robot::srdf::{Group, GroupState, Srdf};
use ember_engine::robot::{self_collision, Geometry, Link, Motion, Robot, RobotArgs, RobotSpec};
use std::process::ExitCode;

pub fn run(command: RobotCommand) -> anyhow::Result<ExitCode> {
    match command {
        RobotCommand::Check(a) => check(a),
        RobotCommand::Primitives(a) => primitives(a),
    }
}

fn spec_of(positional: &Option<String>, args: &RobotArgs) -> RobotSpec {
    let mut spec = args.spec("fetch");
    if let Some(r) = positional {
        spec.robot = r.clone();
    }
    spec
}

fn check(args: RobotCheckArgs) -> anyhow::Result<ExitCode> {
    let spec = spec_of(&args.robot_positional, &args.robot);
    let t = std::time::Instant::now();
    let robot = super::load_robot(&spec)?;
    let load_s = t.elapsed().as_secs_f64();
    let info = robot.load_info();
    println!(
        "robot {} — group {} ({} joints), tip {}",
        robot.name(),
        robot.group_name(),
        robot.dof(),
        robot.links()[robot.tip()].name
    );
    println!("  from {}", info.sources.join(", "));
    if let Some((name, kind)) = &info.virtual_joint {
        println!("  virtual joint {name} ({kind}): planning is in the root link's frame");
    }
    for (name, link) in &info.end_effectors {
        println!("  end effector {name} on {link}");
    }
    println!("\njoints (configuration order): position limits; velocity, acceleration, jerk limits (- not given)");
    let limit = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x}"));
    for (v, l) in robot.variables().iter().zip(robot.limits()) {
        let kind = robot
            .links()
            .iter()
            .find(|l| l.joint == v.name)
            .map(|l| match l.motion {
                Motion::Prismatic { .. } => "prismatic",
                _ if v.continuous => "continuous",
                _ => "revolute",
            })
            .unwrap_or("?");
        println!(
            "  {:<28} {:<10} [{:.4}, {:.4}]  v {} a {} j {}",
            v.name,
            kind,
            v.lower,
            v.upper,
            limit(l.velocity),
            limit(l.acceleration),
            limit(l.jerk)
        );
    }
    for p in robot.passive_joints() {
        println!(
            "  {:<28} outside the group, at {} (requests' start states set it)",
            p.name, p.value
        );
    }
    let states: Vec<&str> = robot.named_state_names().collect();
    if states.is_empty() {
        println!("named states: none");
    }
    let empty = ember_engine::world::Environment::new();
    let mut exact = ember_engine::collision::exact::ExactChecker::new(&robot, &empty);
    let mut spheres = ember_engine::collision::SphereChecker::new(&robot, &empty);
    for name in states {
        let q = robot.named_state(name).expect("listed");
        let verdict = match (exact.contact(q), spheres.contact(q)) {
            (Some(c), _) => format!("in collision ({c})"),
            (None, Some(c)) => format!("free; the spheres touch ({c})"),
            (None, None) => "free".to_string(),
        };
        println!("named state {name}: {verdict}");
    }

    println!(
        "\n{:<30} {:<44} {:>7} {:>14} {:>9}",
        "link", "geometry", "spheres", "protrusion_mm", "coverage"
    );
    let (mut total_spheres, mut moving_spheres, mut worst) = (0, 0, 0.0f64);
    let (mut covered, mut drawn) = (0.0, 0usize);
    let mut geometry_links = 0;
    for (i, link) in robot.links().iter().enumerate() {
        let spheres: Vec<_> = robot.spheres().link_spheres(i).collect();
        total_spheres += spheres.len();
        if robot.link_moves(i) {
            moving_spheres += spheres.len();
        }
        if link.collision.is_empty() {
            continue;
        }
        geometry_links += 1;
        let q = measure(&link.collision, &spheres, args.coverage_samples, i as u64);
        worst = worst.max(q.protrusion);
        covered += q.coverage * q.samples as f64;
        drawn += q.samples;
        println!(
            "{:<30} {:<44} {:>7} {:>14.1} {:>8.2}%",
            link.name,
            describe(&robot, link),
            spheres.len(),
            q.protrusion * 1e3,
            q.coverage * 100.0
        );
    }
    let build = robot.spheres().build;
    println!(
        "spheres: {total_spheres} on {geometry_links} links ({moving_spheres} on moving links), {} clusters; \
         protrusion at most {:.1} mm, coverage {:.2}% of {drawn} surface points",
        robot.spheres().clusters.len(),
        worst * 1e3,
        100.0 * covered / drawn.max(1) as f64
    );
    println!(
        "model built in {:.3} s ({} links fitted, {} from the disk cache, {} from memory); robot loaded in {load_s:.3} s",
        build.seconds, build.fitted, build.from_disk, build.from_memory
    );

    let names = robot.links();
    println!(
        "\nself-collision: {} link pairs checked",
        robot.self_collision_pairs().len()
    );
    for (a, b) in robot.self_collision_pairs() {
        println!("  {} – {}", names[*a].name, names[*b].name);
    }
    if !info.skipped_pairs.is_empty() {
        let mut reasons: std::collections::BTreeMap<&str, usize> = Default::default();
        for (_, _, r) in &info.skipped_pairs {
            *reasons.entry(r.as_str()).or_default() += 1;
        }
        println!(
            "  {} pairs skipped ({})",
            info.skipped_pairs.len(),
            reasons
                .iter()
                .map(|(r, n)| format!("{r} {n}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if !info.warnings.is_empty() {
        println!("\nwarnings ({}):", info.warnings.len());
        for w in &info.warnings {
            println!("  {w}");
        }
    }

    if let Some(reference) = &args.reference {
        compare_with_reference(&robot, &args, reference)?;
    }
    if let Some(path) = &args.picture {
        let q = match &args.state {
            Some(s) => robot
                .named_state(s)
                .ok_or_else(|| anyhow::anyhow!("robot {} has no named state '{s}'", robot.name()))?
                .to_vec(),
            None => robot
                .named_state_names()
                .next()
                .and_then(|s| robot.named_state(s))
                .map(<[f64]>::to_vec)
                .unwrap_or_else(|| robot.middle()),
        };
        picture::write(&robot, &q, path)?;
        println!(
            "\npicture: {} (grey: geometry, red: spheres; front and side views)",
            path.display()
        );
    }
    if let Some(path) = &args.write_srdf {
        let skipped = self_collision::skipped_pairs(&robot, args.samples, &spec.sphere_cache);
        let srdf = Srdf {
            name: robot.name().to_string(),
            groups: vec![Group {
                name: robot.group_name().to_string(),
                joints: robot.variables().iter().map(|v| v.name.clone()).collect(),
                ..Default::default()
            }],
            states: robot
                .named_state_names()
                .map(|n| GroupState {
                    name: n.to_string(),
                    group: robot.group_name().to_string(),
                    values: robot
                        .variables()
                        .iter()
                        .zip(robot.named_state(n).unwrap_or_default())
                        .map(|(v, x)| (v.name.clone(), *x))
                        .collect(),
                })
                .collect(),
            ..Default::default()
        };
        std::fs::write(path, srdf.write_disabled(robot.name(), &skipped))
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        println!(
            "\nwrote {}: {} disabled pairs from {} random configurations",
            path.display(),
            skipped.len(),
            args.samples
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Our spheres and geometry against another description of the same robot, link by link.
fn compare_with_reference(
    robot: &Robot,
    args: &RobotCheckArgs,
    reference: &std::path::Path,
) -> anyhow::Result<()> {
    let spec = RobotSpec {
        robot: reference.display().to_string(),
        package_paths: args.reference_package_path.clone(),
        ..Default::default()
    };
    let other = super::load_robot(&spec)?;
    println!(
        "\nagainst the reference {} (protrusion: how far ours sticks out of it; coverage: share of \
         its surface inside ours; gap: how far its surface lies outside ours):",
        reference.display()
    );
    println!(
        "{:<30} {:>13} {:>9} {:>7}   {:>13} {:>9} {:>7}",
        "", "spheres", "", "", "geometry", "", ""
    );
    println!(
        "{:<30} {:>13} {:>9} {:>7}   {:>13} {:>9} {:>7}",
        "link", "protrusion_mm", "coverage", "gap_mm", "protrusion_mm", "coverage", "gap_mm"
    );
    let mut sum = [0.0f64; 2];
    let mut worst = [0.0f64; 4];
    let mut n = 0usize;
    for (i, link) in robot.links().iter().enumerate() {
        let Some(j) = other.link_index(&link.name) else {
            continue;
        };
        let theirs = &other.links()[j].collision;
        if link.collision.is_empty() || theirs.is_empty() {
            continue;
        }
        let spheres: Vec<_> = robot.spheres().link_spheres(i).collect();
        // Both measured against the reference geometry, not our own.
        let s: FitQuality = measure(theirs, &spheres, args.coverage_samples, i as u64);
        let g = compare(&link.collision, theirs, args.coverage_samples, i as u64);
        let sp = s.protrusion;
        println!(
            "{:<30} {:>13.1} {:>8.2}% {:>7.1}   {:>13.1} {:>8.2}% {:>7.1}",
            link.name,
            sp * 1e3,
            s.coverage * 100.0,
            s.gap * 1e3,
            g.protrusion * 1e3,
            g.coverage * 100.0,
            g.gap * 1e3
        );
        sum[0] += s.coverage * s.samples as f64;
        sum[1] += g.coverage * g.samples as f64;
        n += s.samples;
        worst[0] = worst[0].max(sp);
        worst[1] = worst[1].max(s.gap);
        worst[2] = worst[2].max(g.protrusion);
        worst[3] = worst[3].max(g.gap);
    }
    println!(
        "over all links: spheres stick out at most {:.1} mm, cover {:.2}% and miss it by at most {:.1} mm; \
         geometry sticks out at most {:.1} mm, covers {:.2}% and misses it by at most {:.1} mm",
        worst[0] * 1e3,
        100.0 * sum[0] / n.max(1) as f64,
        worst[1] * 1e3,
        worst[2] * 1e3,
        100.0 * sum[1] / n.max(1) as f64,
        worst[3] * 1e3
    );
    Ok(())
}

fn describe(robot: &Robot, link: &Link) -> String {
    let info = robot.load_info();
    let meshes: Vec<_> = info.meshes.iter().filter(|m| m.link == link.name).collect();
    let mut parts: Vec<String> = meshes
        .iter()
        .map(|m| {
            format!(
                "mesh {} ({} tris{})",
                m.path
                    .file_name()
                    .map(|f| f.to_string_lossy().to_string())
                    .unwrap_or_default(),
                m.triangles,
                if m.parts > 1 {
                    format!(", {} parts", m.parts)
                } else {
                    String::new()
                }
            )
        })
        .collect();
    for ls in &link.collision {
        if let Geometry::Primitive(s) = &ls.geometry {
            parts.push(match *s {
                Shape::Box { half_extents: h } => format!(
                    "box {:.0}×{:.0}×{:.0} mm",
                    h[0] * 2e3,
                    h[1] * 2e3,
                    h[2] * 2e3
                ),
                Shape::Cylinder {
                    radius,
                    half_length,
                } => format!("cylinder r{:.0} l{:.0} mm", radius * 1e3, half_length * 2e3),
                Shape::Capsule {
                    radius,
                    half_length,
                } => format!("capsule r{:.0} l{:.0} mm", radius * 1e3, half_length * 2e3),
                Shape::Sphere { radius } => format!("sphere r{:.0} mm", radius * 1e3),
            });
        }
    }
    let mut s = parts.join(" + ");
    if s.chars().count() > 44 {
        s = s.chars().take(43).collect::<String>() + "…";
    }
    s
}

fn primitives(args: RobotPrimitivesArgs) -> anyhow::Result<ExitCode> {
    use ember_engine::robot::primitives::fit_primitives;
    let spec = spec_of(&args.robot_positional, &args.robot);
    let robot = super::load_robot(&spec)?;
    println!(
        "<!-- tightest single primitive per collision mesh part of {} -->",
        spec.robot
    );
    for link in robot.links() {
        for ls in &link.collision {
            let Geometry::Convex(hull) = &ls.geometry else {
                continue;
            };
            for (shape, local, stick) in fit_primitives(hull, args.max_parts) {
                let pose = ls.origin * local;
                let (r, p, y) = pose.rotation.euler_angles();
                let t = pose.translation.vector;
                let geometry = match shape {
                    Shape::Box { half_extents: h } => format!(
                        "<box size=\"{:.4} {:.4} {:.4}\"/>",
                        2.0 * h[0],
                        2.0 * h[1],
                        2.0 * h[2]
                    ),
                    Shape::Cylinder {
                        radius,
                        half_length,
                    } => format!(
                        "<cylinder radius=\"{radius:.4}\" length=\"{:.4}\"/>",
                        2.0 * half_length
                    ),
                    Shape::Capsule {
                        radius,
                        half_length,
                    } => format!(
                        "<capsule radius=\"{radius:.4}\" length=\"{:.4}\"/>",
                        2.0 * half_length
                    ),
                    Shape::Sphere { radius } => format!("<sphere radius=\"{radius:.4}\"/>"),
                };
                println!(
                "<!-- {}: sticks out {:.1} mm --><collision><origin xyz=\"{:.4} {:.4} {:.4}\" rpy=\"{:.4} {:.4} {:.4}\"/><geometry>{geometry}</geometry></collision>",
                link.name,
                stick * 1e3,
                t.x,
                t.y,
                t.z,
                r,
                p,
                y
            );
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
