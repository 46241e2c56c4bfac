//! One module per subcommand.

pub mod calibrate;
pub mod check_pose;
pub mod compensate;
pub mod demo;
pub mod demo_justin;
pub mod demo_output;
pub mod diagnose;
pub mod evaluate;
pub mod export_urdf;
pub mod fk;
pub mod learn;
pub mod plan;
pub mod plugins;
pub mod schema;
pub mod simulate;
pub mod validate;

use std::path::Path;

use armcomp_core::Robot;
use armcomp_core::measurement::{MeasurementSet, RowSelection, read_csv};

/// Reads a measurement CSV for `robot` (its markers, hold values and measured chain), keeps
/// the selected rows, and prints the reader's warnings.
pub fn read_measurements(robot: &Robot, path: &Path, rows: Option<&RowSelection>) -> anyhow::Result<MeasurementSet> {
    let mut set = read_csv(path, &robot.csv_layout())?;
    if let Some(rows) = rows {
        set = set.select_rows(rows);
    }
    for w in &set.warnings {
        eprintln!("warning: {w}");
    }
    if set.samples.is_empty() {
        anyhow::bail!("{}: no measurements", path.display());
    }
    Ok(set)
}
