//! One module per subcommand.

pub mod calibrate;
pub mod check_pose;
pub mod compensate;
pub mod demo;
pub mod demo_curve;
pub mod demo_justin;
pub mod demo_output;
pub mod diagnose;
pub mod evaluate;
pub mod export_ros;
pub mod export_urdf;
pub mod fit;
pub mod fk;
pub mod import_bag;
pub mod learn;
pub mod plan;
pub mod plugins;
pub mod schema;
pub mod simulate;
pub mod validate;

use std::path::{Path, PathBuf};

use std::sync::OnceLock;

use armcomp_core::Robot;
use armcomp_core::data::measurement::{MeasurementSet, RowSelection, read_csv};
use armcomp_core::support::io::InputLimits;

/// The user config's input limits, set once at start.
pub static LIMITS: OnceLock<InputLimits> = OnceLock::new();

/// The limits every file the command reads is held to.
pub fn input_limits() -> InputLimits {
    LIMITS.get().copied().unwrap_or_default()
}

/// Reads and builds the robot at `path` ([`armcomp_api::read_robot`]), printing its warnings.
pub fn load_robot(path: &Path) -> armcomp_core::Result<Robot> {
    let robot = armcomp_api::read_robot(path, input_limits())?;
    for w in robot.warnings() {
        eprintln!("warning: {w}");
    }
    Ok(robot)
}

/// Checks, before the computation, that `out` may be written and replaces none of the files
/// the run reads: `robot`'s (its file, URDF, meshes, libraries) and `others`.
pub fn check_output(out: &Path, robot: &Robot, others: &[&Path]) -> anyhow::Result<()> {
    Ok(armcomp_core::support::io::check_output(out, &inputs(robot, others))?)
}

/// Every file the run reads: `robot`'s and `others`.
pub fn inputs(robot: &Robot, others: &[&Path]) -> Vec<PathBuf> {
    let mut files = robot.inputs();
    files.extend(others.iter().map(|p| p.to_path_buf()));
    files
}

/// Checks, before any work, that the report folder `dir` (when one is asked for) may be
/// written: see [`armcomp_api::model_report::check`]; and that the command's other output `out`
/// does not lie in it, where the report's replacing the folder would remove it.
pub fn check_report(dir: Option<&Path>, robot: &Robot, read: &[&Path], out: Option<&Path>) -> anyhow::Result<()> {
    let Some(dir) = dir else { return Ok(()) };
    armcomp_api::model_report::check(dir, &inputs(robot, read))?;
    if let Some(out) = out {
        let folder = |p: &Path| std::fs::canonicalize(p).ok();
        let parent = out
            .parent()
            .map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
        if parent.and_then(folder).is_some_and(|p| Some(p) == folder(dir)) {
            anyhow::bail!(
                "{} lies in the report folder {}, which the report replaces whole: write it elsewhere",
                out.display(),
                dir.display()
            );
        }
    }
    Ok(())
}

/// `--rows`, for every command that reads measurements.
#[derive(clap::Args)]
pub struct Rows {
    /// Use only these rows of the data (0-based, header excluded), comma-separated: `even`,
    /// `odd`, a row `N`, or a half-open range: `A..B` is rows A to B−1 (B excluded, so `0..40`
    /// and `40..` split a file), `A..`, `..B`.
    #[arg(long)]
    pub rows: Option<RowSelection>,
}

/// `--group-by`, for every command that cross-validates.
#[derive(clap::Args)]
pub struct GroupBy {
    /// Hold out whole groups of this CSV column (a session, a day, a station) in each fold of
    /// the cross-validation rather than single poses: folds over clustered poses are
    /// optimistic. `COLUMN:N` cuts a numeric column (a time, a temperature) into N blocks of
    /// consecutive values, as many rows each, and holds out whole blocks. Default: a set-up
    /// column the data have (`session`, `setup`, `set_up`, `ground`, `day`), else by station
    /// for data from several, else by pose.
    #[arg(long, value_name = "COLUMN[:N]")]
    pub group_by: Option<String>,
}

impl GroupBy {
    /// The column's name and each selected row's group (`rows`: the data rows, numbered on
    /// across `files`): `--group-by`'s, else the first set-up column (`session`, `setup`, ...)
    /// every file has, else `None`.
    pub fn groups(&self, files: &[&Path], rows: &[usize]) -> anyhow::Result<Option<(String, Vec<usize>)>> {
        let mut texts = Vec::new();
        for file in files {
            texts.push(armcomp_core::support::io::read_text(file, input_limits())?);
        }
        let tables: Vec<(&str, &Path)> = texts.iter().map(String::as_str).zip(files.iter().copied()).collect();
        Ok(armcomp_api::ops::fit::groups_by_column(
            self.group_by.as_deref(),
            &tables,
            rows,
        )?)
    }

    /// What to say when the folds held out single poses (`grouped_by` is `pose`) of rows that
    /// carry no session, station or time structure the user named: the expected error then
    /// holds for the conditions these rows were measured in, and a time or temperature column
    /// the data have can give folds by blocks of it.
    pub fn one_session_note(&self, files: &[&Path], grouped_by: &str) -> anyhow::Result<Option<String>> {
        if self.group_by.is_some() || grouped_by != "pose" {
            return Ok(None);
        }
        let mut ordering: Vec<String> = Vec::new();
        for file in files {
            let text = armcomp_core::support::io::read_text(file, input_limits())?;
            for c in armcomp_core::data::measurement::ordering_columns(&text, file)? {
                if !ordering.contains(&c) {
                    ordering.push(c);
                }
            }
        }
        let offer = match ordering.first() {
            Some(c) => format!(
                "; the data have `{c}`: `--group-by {c}:5` holds out five blocks of it, which is what to expect \
                 of another time or temperature"
            ),
            None => "; a session, day or station column (`--group-by COLUMN`) or a time or temperature column \
                     (`--group-by COLUMN:N`, N blocks of it) would let the folds hold conditions out"
                .to_string(),
        };
        Ok(Some(format!(
            "the folds held out single poses of rows with no session, station or time structure: the expected \
             error holds for the conditions these rows were measured in (one session), not for other days, \
             temperatures or set-ups{offer}"
        )))
    }
}

/// A count of at least one (`--n`): an empty output is never what was asked for.
pub fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(0) => Err("expected at least 1".into()),
        Ok(n) => Ok(n),
        Err(e) => Err(e.to_string()),
    }
}

/// A finite, positive number (`--spread-mm`): a size of zero, below zero or NaN describes
/// nothing.
pub fn positive(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(v) => Err(format!("expected a finite number above 0, got {v}")),
        Err(e) => Err(e.to_string()),
    }
}

/// Reads a measurement CSV for `robot` (its markers, hold values and measured chain), keeps
/// the selected rows, and prints the reader's warnings.
pub fn read_measurements(robot: &Robot, path: &Path, rows: Option<&RowSelection>) -> anyhow::Result<MeasurementSet> {
    let mut set = read_csv(path, &robot.csv_layout(), input_limits())?;
    for w in &set.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(selection) = rows {
        let total = set.rows.last().map_or(0, |r| r + 1);
        set = set.select_rows(selection);
        if set.samples.is_empty() {
            anyhow::bail!(
                "{}: --rows {selection} selects none of its {total} data rows (numbered from 0, header excluded: 0..{total})",
                path.display()
            );
        }
    }
    Ok(set)
}

/// Reads the measurement files `paths` for `robot`, each its own station named by its file
/// name unless it has a `station` column (see [`MeasurementSet::from_files`]), keeps the
/// selected rows of each, and gives `robot` the data's stations
/// ([`Robot::adopt_stations`]). Returns the data and the stations `robot` did not know.
pub fn read_stations(
    robot: &mut Robot,
    paths: &[PathBuf],
    rows: Option<&RowSelection>,
) -> anyhow::Result<(MeasurementSet, Vec<usize>)> {
    let set = read_station_files(robot, paths, rows)?;
    let new = robot.adopt_stations(&set.stations);
    Ok((set, new))
}

/// The measurement files `paths` as one set of stations, as [`read_stations`] reads them,
/// leaving the robot as it is (the library gives it the stations).
pub fn read_station_files(
    robot: &Robot,
    paths: &[PathBuf],
    rows: Option<&RowSelection>,
) -> anyhow::Result<MeasurementSet> {
    let sets = paths
        .iter()
        .map(|p| read_measurements(robot, p, rows))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let names: Vec<String> = paths
        .iter()
        .map(|p| {
            p.file_stem()
                .map_or_else(|| p.display().to_string(), |s| s.to_string_lossy().into_owned())
        })
        .collect();
    if let Some(twice) = names.iter().enumerate().find(|(i, n)| names[..*i].contains(n)) {
        anyhow::bail!(
            "two --data files are named `{}`: each file is a station named by its file name, so rename one (or give \
             the files a `station` column)",
            twice.1
        );
    }
    Ok(MeasurementSet::from_files(sets, &names))
}

/// The data rows of gross errors (residual `whose` over 5 robust noises), then `what` became of
/// them (nothing when there are none), and a drift of the residuals over the rows.
pub fn print_gross_errors(whose: &str, rows: &[usize], what: &str, drift: Option<&armcomp_core::calibrate::Drift>) {
    if !rows.is_empty() {
        let listed: Vec<String> = rows.iter().map(|r| r.to_string()).collect();
        println!(
            "gross errors (residual {whose}over {} times the robust noise) in data row(s) {}{what}",
            armcomp_core::calibrate::GROSS_ERROR,
            listed.join(", "),
        );
    }
    if let Some(d) = drift {
        print_drift(d);
    }
}

/// A drift of the residuals over the row order, and what causes one.
fn print_drift(d: &armcomp_core::calibrate::Drift) {
    println!(
        "the residual drifts with the row order: {:+.3}, {:+.3}, {:+.3} mm (x, y, z) from the first row to the last \
         (t = {:.1}): a tracker or frame drifting over the session, or poses measured in workspace order, not an \
         effect of the robot",
        d.change_mm[0], d.change_mm[1], d.change_mm[2], d.t
    );
}
