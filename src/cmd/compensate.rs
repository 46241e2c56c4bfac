use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_api::ops::compensate as ops;
use armcomp_core::algorithms::compensate::CompensationMode;
use armcomp_core::support::io::write_atomic;

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
    /// For a model with several stations (each its own measurement frame), the station whose
    /// frame the targets are given in, by the name the data's `station` column gave it.
    #[arg(long)]
    station: Option<String>,
    /// Start configurations: a CSV of joint columns as in measurement files, one row for all
    /// targets or one per target. Joints that do not move the tool (other limbs, the head) and
    /// locked joints keep these values; a joint without a column starts at the robot file's
    /// `hold` value (else 0, or the middle of its limits), one that moves the tool at the
    /// middle of its limits. The columns of the robot's sensors (`[[sensors]]`, as in
    /// measurement files) give the readings the robot stands at now, one row for all targets
    /// or one per target: its tilt then turns and loads the model as a measured row's does.
    #[arg(long)]
    start: Option<PathBuf>,
    /// Joints to keep at their start values besides those that do not move the tool,
    /// comma-separated (e.g. `--lock torso_1_joint,torso_2_joint`).
    #[arg(long, value_delimiter = ',')]
    lock: Vec<String>,
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

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.model)?;
    let units = robot.units();
    let inputs: Vec<&std::path::Path> = std::iter::once(args.targets.as_path())
        .chain(args.start.as_deref())
        .collect();
    super::check_output(&args.out, &robot, &inputs)?;
    let targets = ops::read_targets(&args.targets, units, super::input_limits())?;
    let (starts, sensors) = match &args.start {
        Some(path) => ops::read_starts(path, &robot)?,
        None => (Vec::new(), Vec::new()),
    };
    let joints = ops::Joints {
        sensors,
        ..ops::Joints::new(&robot, starts, ops::locked_by_name(&robot, &args.lock)?)?
    };
    let mode = match args.mode {
        Mode::Paper => CompensationMode::Paper,
        Mode::Exact => CompensationMode::Exact,
    };
    let frame = match (args.frame, &args.station) {
        (Frame::Base, Some(_)) => {
            anyhow::bail!("--station names a measurement frame; it does not go with --frame base")
        }
        (Frame::Measurement, Some(name)) => ops::Frame::Station(ops::station_index(&robot, name)?),
        (Frame::Measurement, None) => ops::Frame::Measurement,
        (Frame::Base, None) => ops::Frame::Base,
    };
    let (lines, targets): (Vec<usize>, Vec<ops::Target>) = targets.into_iter().unzip();
    let describe = |i: usize| format!("{}:{}", args.targets.display(), lines[i]);
    // Ctrl-C ends the process: no result is kept from a batch cut short.
    let never = armcomp_core::support::cancel::Cancel::default();
    let run = ops::run(&robot, &targets, &joints, mode, frame, &describe, &never)?;
    write_atomic(&args.out, run.to_csv(&robot).as_bytes())?;
    eprintln!(
        "wrote {} joint commands to {} ({} mode, targets in the {} frame{})",
        targets.len(),
        args.out.display(),
        match mode {
            CompensationMode::Paper => "paper",
            CompensationMode::Exact => "exact",
        },
        match (args.frame, &args.station) {
            (Frame::Measurement, Some(name)) => format!("station {name}'s measurement"),
            (Frame::Measurement, None) => "measurement".to_string(),
            (Frame::Base, _) => "base".to_string(),
        },
        if run.has_predictor {
            ", with the fitted predictor"
        } else {
            ", no fitted predictor"
        }
    );
    let names = robot.tree().coordinate_names();
    let moved: Vec<&str> = names
        .iter()
        .zip(&run.locked)
        .filter(|(_, locked)| !**locked)
        .map(|(n, _)| n.as_str())
        .collect();
    eprintln!(
        "changed {} of {} joints: {}; the others keep their start{}",
        moved.len(),
        names.len(),
        moved.join(", "),
        if args.lock.is_empty() {
            String::new()
        } else {
            format!(" (locked: {})", args.lock.join(", "))
        }
    );
    if run.unconverged.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    eprintln!(
        "{} target(s) out of reach or not met within {} iterations of exact mode; their commands are the closest \
         found:",
        run.unconverged.len(),
        ops::options().max_shifts
    );
    let lu = units.length.symbol();
    for &(i, miss) in &run.unconverged {
        eprintln!(
            "  {}: the model with its residual misses by {} {lu}",
            describe(i),
            units.len_out(miss)
        );
    }
    Ok(ExitCode::from(2))
}
