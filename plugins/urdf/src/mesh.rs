//! Collision meshes: where a URDF's mesh file is, and the bounding box that stands in for it.
//!
//! URDFs from ROS packages name meshes as `package://<package>/<path>`. The package is looked
//! for in the folders above the URDF (a package's `urdf/` folder sits in the package) and in
//! `ROS_PACKAGE_PATH`; when it is not there the mesh is skipped with a warning, so a bare URDF
//! loads without its package. A plain path that does not exist (a mesh folder not copied, an
//! absolute path from another machine) is skipped the same way, as urdfdom and pinocchio
//! load such files. STL meshes are read
//! and replaced by their axis-aligned bounding box; other formats are skipped with a warning.
//! Reasons for skipping leave out the mesh's name, so that the reader can count them by kind.

use std::path::{Path, PathBuf};

use armcomp_core::model::shape::Shape;
use armcomp_core::support::io::InputLimits;
use nalgebra::{Isometry3, Vector3};

/// What became of a collision geometry.
#[derive(Debug, Clone)]
pub enum MeshOutcome {
    /// A shape with its frame in the collision frame.
    Shape(Isometry3<f64>, Shape),
    /// Nothing usable, with the reason.
    Skipped(String),
}

/// The bounding box of a mesh file, scaled; `dir` is the URDF's folder.
pub fn mesh_bounding_box(
    filename: &str,
    scale: [f64; 3],
    dir: &Path,
    limits: InputLimits,
) -> Result<MeshOutcome, String> {
    let path = match filename.strip_prefix("package://") {
        Some(rest) => match find_in_package(rest, dir) {
            Some(p) => p,
            None => {
                let package = rest.split('/').next().unwrap_or(rest);
                return Ok(MeshOutcome::Skipped(format!(
                    "package `{package}` not found above the URDF or in ROS_PACKAGE_PATH"
                )));
            }
        },
        None => {
            let p = Path::new(filename.strip_prefix("file://").unwrap_or(filename));
            let p = if p.is_absolute() { p.to_path_buf() } else { dir.join(p) };
            if !p.exists() {
                return Ok(MeshOutcome::Skipped(
                    "mesh file not found (a path relative to the URDF's folder, or absolute)".into(),
                ));
            }
            armcomp_core::support::io::check_input_file(&p).map_err(|m| format!("mesh file `{}` {m}", p.display()))?;
            p
        }
    };
    let is_stl = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("stl"));
    if !is_stl {
        return Ok(MeshOutcome::Skipped(
            "not an STL file, and only STL meshes are read (as their bounding box)".into(),
        ));
    }
    let bytes = armcomp_core::support::io::read_bytes(&path, limits).map_err(|e| e.to_string())?;
    let mesh = match stl_io::read_stl(&mut std::io::Cursor::new(bytes)) {
        Ok(m) => m,
        Err(e) => return Ok(MeshOutcome::Skipped(format!("cannot read `{}`: {e}", path.display()))),
    };
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for v in &mesh.vertices {
        let p = Vector3::new(v[0] as f64 * scale[0], v[1] as f64 * scale[1], v[2] as f64 * scale[2]);
        lo = lo.inf(&p);
        hi = hi.sup(&p);
    }
    let size = hi - lo;
    if !(size.iter().all(|s| s.is_finite() && *s > 0.0)) {
        return Ok(MeshOutcome::Skipped("the mesh has no volume (empty or flat)".into()));
    }
    let centre = (lo + hi) / 2.0;
    Ok(MeshOutcome::Shape(
        Isometry3::translation(centre.x, centre.y, centre.z),
        Shape::Box([size.x, size.y, size.z]),
    ))
}

/// `<package>/<path>` in a folder named `<package>` above `dir`, or under `ROS_PACKAGE_PATH`.
fn find_in_package(rest: &str, dir: &Path) -> Option<PathBuf> {
    let (package, inner) = rest.split_once('/')?;
    let dir = std::fs::canonicalize(dir).ok()?;
    let above = dir
        .ancestors()
        .filter(|a| a.file_name().is_some_and(|n| n == package))
        .map(|a| a.join(inner));
    let env = std::env::var("ROS_PACKAGE_PATH").unwrap_or_default();
    let listed: Vec<PathBuf> = std::env::split_paths(&env)
        .filter(|p| !p.as_os_str().is_empty())
        .flat_map(|p| {
            let own = p.file_name().is_some_and(|n| n == package).then(|| p.join(inner));
            std::iter::once(p.join(package).join(inner)).chain(own)
        })
        .collect();
    above.chain(listed).find(|p| p.is_file())
}
