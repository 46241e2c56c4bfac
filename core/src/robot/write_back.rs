//! Writing a robot's parameter values back into its description.

use std::path::Path;

use crate::error::{Error, Result};
use crate::robot::Robot;
use crate::robot::robot_file::RobotFile;

impl Robot {
    /// The description with the current parameter values written back, in the file's units.
    pub fn to_file(&self) -> RobotFile {
        self.file_with(&self.chain_values, &self.error_values)
    }

    /// The model's text for `path` (JSON for `.json`, else TOML). With a fitted predictor it is
    /// the description the robot was built from, whose values the predictor was fitted to (as
    /// `armcomp learn` writes a model); else the current values written back into it (as
    /// `armcomp calibrate` does). The files it names (a URDF) are named relative to `path`'s
    /// folder, so that the model moved with them still loads.
    pub fn to_text_for(&self, path: &Path) -> Result<String> {
        let mut file = if self.predictor().is_some() {
            // Specs are trait objects without `Clone`; a round trip through JSON values copies
            // every number exactly.
            serde_json::to_value(&self.file)
                .and_then(serde_json::from_value)
                .map_err(|e| Error::not_written(path, format!("cannot copy the robot description: {e}")))?
        } else {
            // The values are the file's unless changed since the build; its fit record stays.
            let mut file = self.to_file();
            file.fitted = self.file.fitted.clone();
            file
        };
        if let Some(dir) = folder_of(path) {
            file.kinematics.paths_relative_to(&dir);
        }
        file.to_text_for(path)
    }

    /// The description with other chain and error-model values written back (file units).
    pub fn file_with(&self, chain_values: &[f64], error_values: &[Vec<f64>]) -> RobotFile {
        let mut out = RobotFile {
            name: self.file.name.clone(),
            description: self.file.description.clone(),
            units: self.units(),
            gravity: self.file.gravity,
            kinematics: self.chain.spec_with(chain_values),
            links: self.file.links.clone(),
            points: self.file.points.clone(),
            tool: self.file.tool.clone(),
            payload: self.file.payload.clone(),
            error_models: self
                .error_models
                .iter()
                .zip(error_values)
                .map(|(m, v)| m.spec_with(v))
                .collect(),
            predictor: None,
            fitted_predictor: None,
            predictor_frame: None,
            measurement: self.file.measurement.clone(),
            sensors: self.file.sensors.clone(),
            fixtures: self.file.fixtures.clone(),
            collision: self.file.collision.clone(),
            fixed: self.file.fixed.clone(),
            // New values are a new fit: its record is the caller's to write.
            fitted: None,
        };
        // Predictor specs are not clonable trait objects; round-trip through JSON keeps them.
        if let Some(p) = &self.file.predictor {
            out.predictor = serde_json::to_value(p)
                .ok()
                .and_then(|v| serde_json::from_value(v).ok());
        }
        out
    }
}

/// The folder a file at `path` is in, absolute and with symbolic links resolved when it exists
/// (as a URDF's resolved path is), so that the relative path between them is right.
fn folder_of(path: &Path) -> Option<std::path::PathBuf> {
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::canonicalize(parent)
        .or_else(|_| std::path::absolute(parent))
        .ok()
}
