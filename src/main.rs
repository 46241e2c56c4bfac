//! The `armcomp` command line.

#![forbid(unsafe_code)]

mod cmd;
mod progress;

use std::process::ExitCode;
use std::sync::{Mutex, PoisonError};

use armcomp_core::support::cancel::Cancel;

use clap::{Parser, Subcommand};

/// Calibration and compensation of long, heavy, flexible robot arms.
#[derive(Parser)]
#[command(name = "armcomp", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Let robot files load the run-time plugin libraries they name inside their own folder,
    /// and `--library` load the libraries it names. Loading a library runs its code: allow it
    /// only for files you trust. Libraries in the user config's `plugin_dirs` load without it.
    #[arg(long, global = true)]
    allow_plugins: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Run the main job on a built-in twin (default: rock-drill).
    Demo(cmd::demo::Args),
    /// Forward kinematics: positions of every point and the tool pose.
    Fk(cmd::fk::Args),
    /// Simulated measurements of a truth robot file, with tracker noise.
    Simulate(cmd::simulate::Args),
    /// A ROS 2 bag (MCAP or sqlite3) of joint states and a tracker as a measurement CSV: its
    /// static postures, with the clock offset between the streams estimated and applied.
    ImportBag(cmd::import_bag::Args),
    /// Identify a model from measurements (Levenberg–Marquardt with priors).
    Calibrate(cmd::calibrate::Args),
    /// Choose the model from the data: registration, joint offsets, geometry, error models and a
    /// residual predictor, each scored by nested cross-validation; write the best.
    Fit(cmd::fit::Args),
    /// Find the physical effects a model misses, one by one, scored on held-out poses.
    Diagnose(cmd::diagnose::Args),
    /// Fit the model's residual predictor on measurements and store it in the model.
    Learn(cmd::learn::Args),
    /// Joint commands that put the tool on targets, through the model and its predictor.
    Compensate(cmd::compensate::Args),
    /// Position errors of a model (and its fitted predictor) on measurements, in mm.
    Evaluate(cmd::evaluate::Args),
    /// Measurement poses: even sets, D-optimal subsets, trajectory-similar subsets.
    Plan(cmd::plan::Args),
    /// Check robot files against the schema and semantically.
    Validate(cmd::validate::Args),
    /// Print the JSON Schema of robot files.
    Schema(cmd::schema::Args),
    /// List the registered plugins.
    Plugins(cmd::plugins::Args),
    /// Write a model's identified URDF geometry back as a URDF.
    ExportUrdf(cmd::export_urdf::Args),
    /// Write what a ROS 2 robot reads of a model: calibrated URDF, joint offsets, measurement
    /// frame, manifest.
    ExportRos(cmd::export_ros::Args),
    /// Report self-collisions and collisions with fixtures at a configuration.
    CheckPose(cmd::check_pose::Args),
}

/// The token of the computation running in [`stoppable`]: the first Ctrl-C cancels it, a
/// second (or one while nothing runs there) ends the process.
static STOPPABLE: Mutex<Option<Cancel>> = Mutex::new(None);

/// Runs `work` of a command that keeps its best result when stopped, with the token the first
/// Ctrl-C cancels.
pub fn stoppable<T>(work: impl FnOnce(&Cancel) -> T) -> T {
    let cancel = Cancel::new();
    *STOPPABLE.lock().unwrap_or_else(PoisonError::into_inner) = Some(cancel.clone());
    let out = work(&cancel);
    *STOPPABLE.lock().unwrap_or_else(PoisonError::into_inner) = None;
    out
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // A run stopped by Ctrl-C or `kill` leaves no hidden temporary beside its outputs.
    let _ = ctrlc::set_handler(|| {
        let running = STOPPABLE.lock().unwrap_or_else(PoisonError::into_inner).clone();
        if let Some(cancel) = running.filter(|c| !c.is_cancelled()) {
            cancel.cancel();
            eprintln!("\nstopping: the result so far is kept once the running calibrations end (Ctrl-C again to quit)");
            return;
        }
        armcomp_core::support::io::remove_pending_temporaries();
        std::process::exit(130);
    });
    match armcomp_api::config::apply(cli.allow_plugins) {
        Ok(limits) => {
            let _ = cmd::LIMITS.set(limits);
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            return ExitCode::FAILURE;
        }
    }
    let result = match cli.command {
        Command::Demo(a) => cmd::demo::run(a),
        Command::Fk(a) => cmd::fk::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::ImportBag(a) => cmd::import_bag::run(a),
        Command::Calibrate(a) => cmd::calibrate::run(a),
        Command::Fit(a) => cmd::fit::run(a),
        Command::Diagnose(a) => cmd::diagnose::run(a),
        Command::Learn(a) => cmd::learn::run(a),
        Command::Compensate(a) => cmd::compensate::run(a),
        Command::Evaluate(a) => cmd::evaluate::run(a),
        Command::Plan(a) => cmd::plan::run(a),
        Command::Validate(a) => cmd::validate::run(a),
        Command::Schema(a) => cmd::schema::run(a),
        Command::Plugins(a) => cmd::plugins::run(a),
        Command::ExportUrdf(a) => cmd::export_urdf::run(a),
        Command::ExportRos(a) => cmd::export_ros::run(a),
        Command::CheckPose(a) => cmd::check_pose::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
