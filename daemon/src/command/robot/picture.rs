//! A picture of the sphere model over the robot's geometry at one configuration: front and side
//! orthographic views, geometry in grey (painter's order), spheres as red outlines. SVG or PNG
//! by the file's extension.

use ember_engine::robot::spheres::surface_triangles;
use ember_engine::robot::Robot;
use nalgebra::Point3;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

const VIEW: u32 = 600;

/// Writes the picture of `robot` at `q` to `path` (`.svg` or `.png`).
pub fn write(robot: &Robot, q: &[f64], path: &Path) -> anyhow::Result<()> {
    robot.validate(q)?;
    let poses = robot.link_poses(q)?;
    let mut triangles = Vec::new();
    let mut spheres = Vec::new();
    for (i, link) in robot.links().iter().enumerate() {
        for ls in &link.collision {
            for t in surface_triangles(ls) {
                triangles.push(t.map(|p| (poses[i] * Point3::from(p)).coords.into()));
            }
        }
        for (c, r) in robot.spheres().link_spheres(i) {
            let w: [f64; 3] = (poses[i] * Point3::from(c)).coords.into();
            spheres.push((w, r));
        }
    }
    let size = (2 * VIEW, VIEW);
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "svg" => draw(
            SVGBackend::new(path, size).into_drawing_area(),
            &triangles,
            &spheres,
        ),
        "png" => draw(
            BitMapBackend::new(path, size).into_drawing_area(),
            &triangles,
            &spheres,
        ),
        _ => anyhow::bail!("picture {}: use a .svg or .png file name", path.display()),
    }
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    triangles: &[[[f64; 3]; 3]],
    spheres: &[([f64; 3], f64)],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(VIEW);
    // Front: looking along -x (horizontal y, vertical z); side: looking along +y (x, z).
    for (area, h_axis, depth_axis, flip) in [(left, 1, 0, true), (right, 0, 1, false)] {
        let all = triangles
            .iter()
            .flatten()
            .copied()
            .chain(spheres.iter().map(|(c, _)| *c));
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in all {
            let h = if flip { -p[h_axis] } else { p[h_axis] };
            lo = [lo[0].min(h), lo[1].min(p[2])];
            hi = [hi[0].max(h), hi[1].max(p[2])];
        }
        let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-6) * 1.1;
        let scale = VIEW as f64 / span;
        let mid = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let px = |p: &[f64; 3]| -> (i32, i32) {
            let h = if flip { -p[h_axis] } else { p[h_axis] };
            (
                ((h - mid[0]) * scale + VIEW as f64 / 2.0) as i32,
                (VIEW as f64 / 2.0 - (p[2] - mid[1]) * scale) as i32,
            )
        };
        // Farthest first: the viewer looks along -depth for the front view, +depth for the side.
        let depth = |t: &[[f64; 3]; 3]| {
            let d = (t[0][depth_axis] + t[1][depth_axis] + t[2][depth_axis]) / 3.0;
            if flip {
                d
            } else {
                -d
            }
        };
        let mut order: Vec<&[[f64; 3]; 3]> = triangles.iter().collect();
        order.sort_by(|a, b| depth(a).total_cmp(&depth(b)));
        for t in order {
            let pts: Vec<(i32, i32)> = t.iter().map(px).collect();
            area.draw(&Polygon::new(pts.clone(), RGBColor(200, 200, 205).filled()))?;
            area.draw(&PathElement::new(
                vec![pts[0], pts[1], pts[2], pts[0]],
                RGBColor(150, 150, 160).stroke_width(1),
            ))?;
        }
        for (c, r) in spheres {
            area.draw(&Circle::new(
                px(c),
                ((r * scale) as i32).max(1),
                RGBColor(220, 40, 40).mix(0.7).stroke_width(1),
            ))?;
        }
    }
    root.present()?;
    Ok(())
}
