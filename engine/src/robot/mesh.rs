//! Collision meshes: resolving URDF mesh URIs, reading STL (binary and ASCII), OBJ and COLLADA
//! through `mesh-loader`, checking them, and turning them into convex hulls (one per mesh, or
//! one per part of a convex decomposition when the mesh is clearly not convex).

use crate::collision::convex::ConvexHull;
use rustc_hash::FxHashMap;
use std::path::{Path, PathBuf};

/// Meshes with more triangles are refused (collision meshes are meant to be simplified).
pub const MAX_TRIANGLES: usize = 1_000_000;

/// Mesh files larger than this are refused before they are read.
const MAX_FILE_BYTES: u64 = 256 << 20;

/// A closed mesh whose hull exceeds its volume by more than this share is decomposed.
const CONCAVITY_LIMIT: f64 = 0.15;

/// Where `package://` URIs are looked up, in order: `--package-path` folders, then
/// `ROS_PACKAGE_PATH`, then `AMENT_PREFIX_PATH` (`<prefix>/share`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PackagePaths {
    /// Folders given explicitly (searched first).
    pub explicit: Vec<PathBuf>,
}

impl PackagePaths {
    /// Folders to search, explicit first, then the ROS environment variables.
    pub fn search_dirs(&self) -> Vec<PathBuf> {
        let mut dirs = self.explicit.clone();
        if let Ok(v) = std::env::var("ROS_PACKAGE_PATH") {
            dirs.extend(v.split(':').filter(|s| !s.is_empty()).map(PathBuf::from));
        }
        if let Ok(v) = std::env::var("AMENT_PREFIX_PATH") {
            dirs.extend(
                v.split(':')
                    .filter(|s| !s.is_empty())
                    .map(|p| Path::new(p).join("share")),
            );
        }
        dirs
    }

    /// The folder of package `name`: `<dir>/<name>`, or a search folder itself named `name`.
    pub fn find(&self, name: &str) -> Result<PathBuf, String> {
        let dirs = self.search_dirs();
        for d in &dirs {
            if d.file_name().is_some_and(|f| f == name) && d.is_dir() {
                return Ok(d.clone());
            }
            let p = d.join(name);
            if p.is_dir() {
                return Ok(p);
            }
        }
        let searched = if dirs.is_empty() {
            "no package folders are set: pass --package-path DIR or set ROS_PACKAGE_PATH".into()
        } else {
            format!(
                "searched {}",
                dirs.iter()
                    .map(|d| d.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        Err(format!("unknown package '{name}' ({searched})"))
    }
}

/// The file a URDF mesh `uri` names: `package://pkg/rel`, `file:///abs`, or a path relative
/// to the URDF's folder `base`.
pub fn resolve(uri: &str, base: &Path, packages: &PackagePaths) -> Result<PathBuf, String> {
    if let Some(rest) = uri.strip_prefix("package://") {
        let (pkg, rel) = rest
            .split_once('/')
            .ok_or_else(|| format!("mesh URI '{uri}' names no file inside the package"))?;
        return Ok(packages.find(pkg)?.join(rel));
    }
    if let Some(path) = uri.strip_prefix("file://") {
        return Ok(PathBuf::from(path));
    }
    if uri.contains("://") {
        return Err(format!(
            "mesh URI '{uri}' uses an unsupported scheme (package:// and file:// are supported)"
        ));
    }
    Ok(base.join(uri))
}

/// A triangle mesh in metres (scale applied).
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleMesh {
    /// Vertices.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles over `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

/// Reads a mesh file (format from its extension) and applies `scale`.
pub fn read_mesh(path: &Path, scale: [f64; 3]) -> Result<TriangleMesh, String> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if !matches!(ext.as_str(), "stl" | "obj" | "dae") {
        return Err(format!(
            "mesh {} has an unsupported format (STL, OBJ and COLLADA .dae are supported)",
            path.display()
        ));
    }
    let meta = std::fs::metadata(path)
        .map_err(|e| format!("mesh {} cannot be read: {e}", path.display()))?;
    if meta.len() > MAX_FILE_BYTES {
        return Err(format!(
            "mesh {} is {} MB, more than the {} MB Ember reads; simplify it",
            path.display(),
            meta.len() >> 20,
            MAX_FILE_BYTES >> 20
        ));
    }
    let loader = mesh_loader::Loader::default().merge_meshes(true);
    let scene = std::panic::catch_unwind(|| loader.load(path))
        .map_err(|_| format!("mesh {} could not be parsed", path.display()))?
        .map_err(|e| format!("mesh {} could not be parsed: {e}", path.display()))?;
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for m in &scene.meshes {
        let base = vertices.len() as u32;
        vertices.extend(m.vertices.iter().map(|v| {
            [
                v[0] as f64 * scale[0],
                v[1] as f64 * scale[1],
                v[2] as f64 * scale[2],
            ]
        }));
        for f in &m.faces {
            if f.iter().any(|&i| i as usize >= m.vertices.len()) {
                return Err(format!(
                    "mesh {} has a face referring to a missing vertex",
                    path.display()
                ));
            }
            triangles.push(f.map(|i| i + base));
        }
        if triangles.len() > MAX_TRIANGLES {
            break;
        }
    }
    let mesh = TriangleMesh {
        vertices,
        triangles,
    };
    mesh.check()
        .map_err(|m| format!("mesh {} {m}", path.display()))?;
    Ok(mesh)
}

impl TriangleMesh {
    /// Refuses empty, huge and non-finite meshes.
    pub fn check(&self) -> Result<(), String> {
        if self.triangles.is_empty() {
            return Err("is empty (no triangles)".into());
        }
        if self.triangles.len() > MAX_TRIANGLES {
            return Err(format!(
                "has more than {MAX_TRIANGLES} triangles; simplify it (collision meshes need \
                 a few thousand at most)"
            ));
        }
        if self.vertices.iter().flatten().any(|v| !v.is_finite()) {
            return Err("has a non-finite vertex coordinate".into());
        }
        Ok(())
    }

    /// Why the mesh is not a manifold surface (an edge shared by more than two triangles once
    /// equal vertices are merged), if it is not. Such meshes are still usable through their
    /// convex hull (official Panda meshes have such edges; MoveIt accepts them), so this is a
    /// warning, not an error.
    pub fn manifold_issue(&self) -> Option<String> {
        let (welded, _) = self.welded();
        let mut uses: FxHashMap<(u32, u32), u32> = FxHashMap::default();
        for t in &welded {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                continue; // degenerate triangle: ignored
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let n = uses.entry((a.min(b), a.max(b))).or_insert(0);
                *n += 1;
                if *n > 2 {
                    let p = self.vertices[a as usize];
                    return Some(format!(
                        "is non-manifold: an edge at ({:.4}, {:.4}, {:.4}) is shared by more \
                         than two triangles",
                        p[0], p[1], p[2]
                    ));
                }
            }
        }
        None
    }

    /// Triangles over merged vertices (equal coordinates share one index), and whether every
    /// edge then has exactly two triangles (a closed surface).
    fn welded(&self) -> (Vec<[u32; 3]>, bool) {
        let mut index: FxHashMap<[u64; 3], u32> = FxHashMap::default();
        let map: Vec<u32> = self
            .vertices
            .iter()
            .enumerate()
            .map(|(i, v)| *index.entry(v.map(f64::to_bits)).or_insert(i as u32))
            .collect();
        let tris: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .map(|t| t.map(|i| map[i as usize]))
            .collect();
        let mut uses: FxHashMap<(u32, u32), u32> = FxHashMap::default();
        for t in &tris {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        let closed = uses.values().all(|&n| n == 2);
        (tris, closed)
    }

    /// Signed volume (meaningful for closed surfaces).
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| nalgebra::Vector3::from(self.vertices[i as usize]));
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum()
    }

    /// Convex parts covering the mesh: its hull, or, for a closed mesh whose hull is more than
    /// 15% larger than it, the hulls of a convex decomposition (parry3d's V-HACD).
    pub fn convex_parts(&self) -> Result<Vec<ConvexHull>, String> {
        let hull = ConvexHull::of_points(&self.vertices).map_err(|e| e.to_string())?;
        let (_, closed) = self.welded();
        let volume = self.volume().abs();
        if !closed || volume <= 0.0 || hull.volume() <= volume * (1.0 + CONCAVITY_LIMIT) {
            return Ok(vec![hull]);
        }
        let points: Vec<parry3d::math::Vector> = self
            .vertices
            .iter()
            .map(|p| parry3d::math::Vector::new(p[0] as f32, p[1] as f32, p[2] as f32))
            .collect();
        let params = parry3d::transformation::vhacd::VHACDParameters::default();
        let decomposition = parry3d::transformation::vhacd::VHACD::decompose(
            &params,
            &points,
            &self.triangles,
            true,
        );
        let parts: Vec<ConvexHull> = decomposition
            .compute_exact_convex_hulls(&points, &self.triangles)
            .into_iter()
            .filter_map(|(pts, _)| {
                let p: Vec<[f64; 3]> = pts
                    .iter()
                    .map(|v| [v.x as f64, v.y as f64, v.z as f64])
                    .collect();
                ConvexHull::of_points(&p).ok()
            })
            .collect();
        if parts.is_empty() {
            Ok(vec![hull])
        } else {
            Ok(parts)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> TriangleMesh {
        TriangleMesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn closed_tetrahedron_passes_and_is_its_own_hull() {
        let sut = tetra();
        sut.check().unwrap();
        assert!((sut.volume() - 1.0 / 6.0).abs() < 1e-12);
        let parts = sut.convex_parts().unwrap();
        assert_eq!(parts.len(), 1);
        assert!((parts[0].volume() - 1.0 / 6.0).abs() < 1e-6);
    }

    #[test]
    fn an_edge_with_three_triangles_is_non_manifold() {
        let mut sut = tetra();
        sut.vertices.push([1.0, 1.0, 1.0]);
        sut.triangles.push([1, 2, 4]);
        sut.check().unwrap();
        let issue = sut.manifold_issue().unwrap();
        assert!(issue.contains("non-manifold"), "{issue}");
        assert_eq!(tetra().manifold_issue(), None);
    }

    #[test]
    fn a_mesh_of_millions_of_triangles_is_refused() {
        let sut = TriangleMesh {
            vertices: tetra().vertices,
            triangles: vec![[0, 1, 2]; MAX_TRIANGLES + 1],
        };
        let err = sut.check().unwrap_err();
        assert!(err.contains("more than 1000000 triangles"), "{err}");
    }

    #[test]
    fn empty_mesh_is_refused() {
        let sut = TriangleMesh {
            vertices: vec![],
            triangles: vec![],
        };
        assert!(sut.check().unwrap_err().contains("empty"));
    }

    #[test]
    fn uris_resolve_through_packages_files_and_relative_paths() {
        let dir = std::env::temp_dir().join(format!("ember-pkg-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("my_robot/meshes")).unwrap();
        let packages = PackagePaths {
            explicit: vec![dir.clone()],
        };
        let base = Path::new("/robots/x");
        assert_eq!(
            resolve("package://my_robot/meshes/a.stl", base, &packages).unwrap(),
            dir.join("my_robot/meshes/a.stl")
        );
        assert_eq!(
            resolve("file:///abs/a.stl", base, &packages).unwrap(),
            PathBuf::from("/abs/a.stl")
        );
        assert_eq!(
            resolve("meshes/a.stl", base, &packages).unwrap(),
            PathBuf::from("/robots/x/meshes/a.stl")
        );
        let err = resolve("package://nope/a.stl", base, &packages).unwrap_err();
        assert!(err.contains("unknown package 'nope'"), "{err}");
        assert!(resolve("http://x/a.stl", base, &packages).is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}
