//! Loading what `--robot` names: a robot file (TOML, JSON) or a bare URDF.

use std::path::Path;

use armcomp_core::data::measurement::MeasurementSet;
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

/// `robot` given the stations of `data` ([`Robot::adopt_stations`]): a station the robot file
/// names keeps its frame, a new one starts at the robot's measurement frame, which calibration
/// then registers in closed form on the station's own samples and refines. `None` when `robot`
/// has the data's stations already (or the data one and the robot none): use it as it is.
/// Data with a station of fewer than three measured positions are refused
/// ([`check_station_rows`](armcomp_core::calibrate::check_station_rows)).
pub fn with_stations(robot: &Robot, data: &MeasurementSet) -> Result<Option<Robot>> {
    let known: Vec<&str> = robot.stations().iter().map(|s| s.name.as_str()).collect();
    let wanted: Vec<&str> = data.stations.iter().map(String::as_str).collect();
    if known == wanted || (known.is_empty() && wanted.len() <= 1) {
        armcomp_core::calibrate::check_station_rows(robot, &data.samples)?;
        return Ok(None);
    }
    let mut adopted = robot.rebuild(robot.to_file())?;
    adopted.adopt_stations(&data.stations);
    armcomp_core::calibrate::check_station_rows(&adopted, &data.samples)?;
    Ok(Some(adopted))
}
