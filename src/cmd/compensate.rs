use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use armcomp_core::Units;
use armcomp_core::compensate::{CompensationMode, CompensationOptions, Compensator, mid_range};
use armcomp_core::ik::IkTarget;
use armcomp_core::io::write_atomic;
use armcomp_core::measurement::{joint_header, joint_row, split_header};
use armcomp_core::units::LengthUnit;
use nalgebra::{Isometry3, Point3, Quaternion, UnitQuaternion, Vector3};

#[derive(clap::Args)]
pub struct Args {
    /// The model: a robot or model file; its fitted predictor (from `armcomp learn`) is used
    /// when it carries one.
    #[arg(long)]
    model: PathBuf,
    /// Targets CSV: columns x, y, z with units in the header (`x[mm]`), else the model's length
    /// unit, and optionally qw, qx, qy, qz: a tool orientation to keep (unit quaternion, same
    /// frame as the position); `#` starts a comment line.
    #[arg(long)]
    targets: PathBuf,
    /// Output CSV of joint commands and corrected targets (written atomically).
    #[arg(long)]
    out: PathBuf,
    /// `exact` solves the model including the predicted residual; `paper` is the deflection
    /// paper's two-step (IK, predict, shift the target, IK again).
    #[arg(long, value_enum, default_value = "exact")]
    mode: Mode,
    /// Frame of the targets and of the corrected targets written: `measurement` (the tracker's,
    /// as in measurement files) or `base` (the robot base).
    #[arg(long, value_enum, default_value = "measurement")]
    frame: Frame,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Mode {
    Paper,
    Exact,
}

#[derive(Clone, Copy, PartialEq, clap::ValueEnum)]
enum Frame {
    Measurement,
    Base,
}

/// One target of the CSV: its line, position (m) and, with the `qw, qx, qy, qz` columns, the
/// tool orientation to keep.
struct Target {
    line: usize,
    position: Vector3<f64>,
    orientation: Option<UnitQuaternion<f64>>,
}

/// Reads `x, y, z` targets (m) and optional `qw, qx, qy, qz` orientations with their line
/// numbers, erroring with file, line and column.
fn read_targets(path: &Path, units: Units) -> anyhow::Result<Vec<Target>> {
    let text = armcomp_core::io::read_text(path)?;
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((header_line, header)) = lines.next() else {
        bail!("{}: empty; expected a header `x[mm],y[mm],z[mm]`", path.display());
    };
    // Columns 0..3 are x, y, z (with their scale to m), 3..7 are qw, qx, qy, qz (scale 1).
    let mut columns: [Option<(usize, f64)>; 7] = [None; 7];
    let mut n_columns = 0;
    for (c, h) in header.split(',').enumerate() {
        n_columns += 1;
        let (name, unit) = split_header(h);
        let Some(slot) = ["x", "y", "z", "qw", "qx", "qy", "qz"].iter().position(|n| *n == name) else {
            bail!(
                "{}:{header_line}: column {}: unexpected `{h}`; expected x, y, z with a length unit, e.g. `x[mm]`, and optionally qw, qx, qy, qz",
                path.display(),
                c + 1
            );
        };
        let scale = match (slot, unit) {
            (0..3, None) => units.length.to_si(),
            (0..3, Some(u)) => LengthUnit::parse(u).map(LengthUnit::to_si).with_context(|| {
                format!(
                    "{}:{header_line}: column {}: unknown length unit `{u}` (expected m, cm, mm or in)",
                    path.display(),
                    c + 1
                )
            })?,
            (_, None) => 1.0,
            (_, Some(u)) => bail!(
                "{}:{header_line}: column {}: a quaternion component has no unit, found `[{u}]`",
                path.display(),
                c + 1
            ),
        };
        if columns[slot].replace((c, scale)).is_some() {
            bail!("{}:{header_line}: column `{name}` appears twice", path.display());
        }
    }
    if columns[..3].iter().any(Option::is_none) {
        bail!("{}:{header_line}: expected the columns x, y and z", path.display());
    }
    let with_orientation = match columns[3..].iter().filter(|c| c.is_some()).count() {
        0 => false,
        4 => true,
        _ => bail!(
            "{}:{header_line}: an orientation needs all four columns qw, qx, qy, qz",
            path.display()
        ),
    };
    let mut targets = Vec::new();
    for (line, row) in lines {
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        if cells.len() != n_columns {
            bail!(
                "{}:{line}: {} values, the header has {n_columns}",
                path.display(),
                cells.len()
            );
        }
        let mut values = [0.0; 7];
        for (value, &(c, scale)) in values
            .iter_mut()
            .zip(&columns)
            .filter_map(|(v, c)| c.as_ref().map(|c| (v, c)))
        {
            let v: f64 = cells[c].parse().ok().filter(|v: &f64| v.is_finite()).with_context(|| {
                format!(
                    "{}:{line}: column {}: `{}` is not a finite number",
                    path.display(),
                    c + 1,
                    cells[c]
                )
            })?;
            *value = v * scale;
        }
        let orientation = if with_orientation {
            let q = Quaternion::new(values[3], values[4], values[5], values[6]);
            // The same tolerance as measurement files: rounded quaternions are renormalised.
            if (q.norm() - 1.0).abs() > 1e-3 {
                bail!(
                    "{}:{line}: orientation quaternion has norm {:.6}, expected 1",
                    path.display(),
                    q.norm()
                );
            }
            Some(UnitQuaternion::from_quaternion(q))
        } else {
            None
        };
        targets.push(Target {
            line,
            position: Vector3::new(values[0], values[1], values[2]),
            orientation,
        });
    }
    if targets.is_empty() {
        bail!("{}: no targets", path.display());
    }
    Ok(targets)
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = armcomp::load_robot(&args.model)?;
    let units = robot.file.units;
    super::check_output(&args.out, &robot, &[&args.targets])?;
    let targets = read_targets(&args.targets, units)?;
    let mode = match args.mode {
        Mode::Paper => CompensationMode::Paper,
        Mode::Exact => CompensationMode::Exact,
    };
    let options = CompensationOptions::default();
    let mut comp = Compensator::for_model(&robot, options)?;
    let t_meas_base = robot.t_meas_base();
    let q0 = mid_range(&robot);
    let mut rows = Vec::with_capacity(targets.len());
    let mut stds = Vec::with_capacity(targets.len());
    // Exact-mode targets where the model with the residual still misses (line, m).
    let mut unconverged = Vec::new();
    for Target {
        line,
        position,
        orientation,
    } in &targets
    {
        let to_base = match args.frame {
            Frame::Measurement => t_meas_base.inverse(),
            Frame::Base => Isometry3::identity(),
        };
        let position = to_base.transform_point(&Point3::from(*position)).coords;
        let target = match orientation {
            Some(r) => IkTarget::Pose(Isometry3::from_parts(position.into(), to_base.rotation * r)),
            None => IkTarget::Position(position),
        };
        let c = comp
            .compensate_target(&target, &q0, mode)
            .with_context(|| format!("{}:{line}", args.targets.display()))?;
        if mode == CompensationMode::Exact && c.mismatch > options.tolerance {
            unconverged.push((*line, c.mismatch));
        }
        let corrected = match args.frame {
            Frame::Measurement => t_meas_base.transform_point(&Point3::from(c.corrected_target)).coords,
            Frame::Base => c.corrected_target,
        };
        let mut row = joint_row(comp.q(), robot.tree(), units);
        row.extend(corrected.iter().map(|v| units.len_out(*v).to_string()));
        rows.push(row);
        stds.push(comp.residual_std());
    }
    let lu = units.length.symbol();
    let mut out = joint_header(robot.tree(), units).join(",");
    write!(out, ",x_cmd[{lu}],y_cmd[{lu}],z_cmd[{lu}]")?;
    // Predictors with a predictive standard deviation (the GP) add it, measurement frame.
    let with_std = stds.iter().all(Option::is_some);
    if with_std {
        write!(out, ",std_x[{lu}],std_y[{lu}],std_z[{lu}]")?;
    }
    out.push('\n');
    for (row, std) in rows.iter().zip(&stds) {
        out.push_str(&row.join(","));
        if let (true, Some(s)) = (with_std, std) {
            for v in s.iter() {
                write!(out, ",{}", units.len_out(*v))?;
            }
        }
        out.push('\n');
    }
    write_atomic(&args.out, out.as_bytes())?;
    eprintln!(
        "wrote {} joint commands to {} ({} mode, targets in the {} frame{})",
        targets.len(),
        args.out.display(),
        match mode {
            CompensationMode::Paper => "paper",
            CompensationMode::Exact => "exact",
        },
        match args.frame {
            Frame::Measurement => "measurement",
            Frame::Base => "base",
        },
        if comp.has_predictor() {
            ", with the fitted predictor"
        } else {
            ", no fitted predictor"
        }
    );
    if unconverged.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    eprintln!(
        "exact mode did not converge for {} target(s) within {} iterations; their commands are the closest found:",
        unconverged.len(),
        options.max_shifts
    );
    for (line, miss) in &unconverged {
        eprintln!(
            "  {}:{line}: the model with the residual misses by {} {lu}",
            args.targets.display(),
            units.len_out(*miss)
        );
    }
    Ok(ExitCode::from(2))
}
