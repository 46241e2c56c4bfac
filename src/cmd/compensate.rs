use std::path::PathBuf;
use std::process::ExitCode;

use armcomp::ops::compensate as ops;
use armcomp_core::compensate::CompensationMode;
use armcomp_core::io::write_atomic;

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

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = armcomp::load_robot(&args.model)?;
    let units = robot.units();
    super::check_output(&args.out, &robot, &[&args.targets])?;
    let targets = ops::read_targets(&args.targets, units)?;
    let mode = match args.mode {
        Mode::Paper => CompensationMode::Paper,
        Mode::Exact => CompensationMode::Exact,
    };
    let frame = match args.frame {
        Frame::Measurement => ops::Frame::Measurement,
        Frame::Base => ops::Frame::Base,
    };
    let (lines, targets): (Vec<usize>, Vec<ops::Target>) = targets.into_iter().unzip();
    let describe = |i: usize| format!("{}:{}", args.targets.display(), lines[i]);
    let run = ops::run(&robot, &targets, mode, frame, &describe)?;
    write_atomic(&args.out, run.to_csv(&robot).as_bytes())?;
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
        if run.has_predictor {
            ", with the fitted predictor"
        } else {
            ", no fitted predictor"
        }
    );
    if run.unconverged.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    eprintln!(
        "exact mode did not converge for {} target(s) within {} iterations; their commands are the closest found:",
        run.unconverged.len(),
        ops::options().max_shifts
    );
    let lu = units.length.symbol();
    for &(i, miss) in &run.unconverged {
        eprintln!(
            "  {}: the model with the residual misses by {} {lu}",
            describe(i),
            units.len_out(miss)
        );
    }
    Ok(ExitCode::from(2))
}
