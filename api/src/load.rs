//! Loading what `--robot` names: a robot file (TOML, JSON) or a bare URDF.

use std::path::Path;

use armcomp_core::support::io::InputLimits;
use armcomp_core::{Result, Robot};

/// Whether `path` names a URDF file (by its extension).
pub fn is_urdf(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("urdf"))
}

/// Reads and builds the robot at `path`: a bare `.urdf` (SI units, a point at every link's
/// origin, see [`armcomp_urdf::robot_file_for_urdf`]) or a robot file. What was skipped while
/// reading (meshes that cannot be found) is in [`Robot::warnings`]. Every file is read within
/// `limits`.
pub fn read_robot(path: &Path, limits: InputLimits) -> Result<Robot> {
    if is_urdf(path) {
        armcomp_urdf::robot_from_urdf(path, limits)
    } else {
        Robot::from_path_with(path, limits)
    }
}
