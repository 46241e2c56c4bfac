use std::path::{Path, PathBuf};
use std::process::ExitCode;

use armcomp_api::ops::export_ros::{self as ops, CheckedAt};
use armcomp_api::ops::export_urdf::{inexpressible, rigid, rigid_deviation};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::support::io::{check_report_folder, read_bytes, write_folder_atomic};

use super::export_urdf::refuse_inexpressible;
use super::{input_limits, inputs, read_measurements};

#[derive(clap::Args)]
pub struct Args {
    /// Robot or model file (TOML, JSON) whose kinematics is `type = "urdf"`.
    #[arg(long)]
    model: PathBuf,
    /// Output folder (written atomically as a whole; new, or an earlier export): calibrated.urdf,
    /// joint_offsets.yaml, measurement_frame.yaml and manifest.json.
    #[arg(long)]
    out: PathBuf,
    /// Measurement CSV whose joint values the reloaded URDF is checked at (else `--samples`
    /// configurations drawn at random within the limits); with `--rigid-only`, also what the
    /// dropped models are measured on.
    #[arg(long)]
    data: Option<PathBuf>,
    /// Configurations the reloaded URDF is checked at without `--data`.
    #[arg(long, default_value_t = 200)]
    samples: usize,
    /// Seed of those configurations.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The measurement (tracker) frame's name in the static transform; its child is the URDF's
    /// root link.
    #[arg(long, default_value = "tracker")]
    measurement_frame: String,
    /// Export the rigid geometry of a model whose error models or fitted predictor URDF cannot
    /// express, dropping them; needs `--data` to state how far that moves the measured points.
    #[arg(long, requires = "data")]
    rigid_only: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.model)?;
    let dropped = inexpressible(&robot);
    refuse_inexpressible(&args.model, &dropped, args.rigid_only)?;
    let urdf = armcomp_urdf::calibrated_urdf(&robot)?;
    let data: Vec<&Path> = args.data.iter().map(|p| p.as_path()).collect();
    let read = inputs(&robot, &[&[urdf.source.as_path()], data.as_slice()].concat());
    check_report_folder(&args.out, &ops::is_export_file, &read)?;
    let (configurations, checked, samples) = match &args.data {
        Some(path) => {
            let set = read_measurements(&robot, path, None)?;
            let bytes = read_bytes(path, input_limits())?;
            let checked = CheckedAt::Measured {
                file: path.display().to_string(),
                sha256: ops::sha256_hex(&bytes),
                rows: set.samples.len(),
            };
            (set.samples.iter().map(|s| s.q.clone()).collect(), checked, set.samples)
        }
        None => {
            let qs = configurations(robot.tree(), Sampler::Random, args.samples, args.seed)?;
            let checked = CheckedAt::Sampled {
                n: args.samples,
                seed: args.seed,
            };
            (qs, checked, Vec::new())
        }
    };
    let rigid_model = if dropped.is_empty() { None } else { Some(rigid(&robot)?) };
    let model_bytes = read_bytes(&args.model, input_limits())?;
    let export = ops::export(
        &robot,
        rigid_model.as_ref().unwrap_or(&robot),
        &urdf,
        &args.model,
        &model_bytes,
        &configurations,
        checked,
        &args.measurement_frame,
        &args.out,
    )?;
    write_folder_atomic(&args.out, &export.files)?;
    eprintln!(
        "wrote {} ({}, {}, {}, {}); the URDF, read back, is within {:.1e} m of the model at {} configurations (largest {:.1e} m)",
        args.out.display(),
        ops::URDF_FILE,
        ops::OFFSETS_FILE,
        ops::TRANSFORM_FILE,
        ops::MANIFEST_FILE,
        ops::RELOAD_TOLERANCE,
        export.configurations,
        export.reload_deviation
    );
    eprintln!(
        "  joint offsets relative to {}: the source URDF with them misses the tool by up to {:.3} mm (the rest of the identified geometry is only in {})",
        urdf.source.display(),
        export.offsets_only_deviation * 1e3,
        ops::URDF_FILE
    );
    let t = export.t_meas_base.translation.vector;
    eprintln!(
        "  measurement frame: `{}` -> base at [{:.6}, {:.6}, {:.6}] m",
        args.measurement_frame, t.x, t.y, t.z
    );
    if !dropped.is_empty() {
        let max = rigid_deviation(&robot, &samples)?;
        eprintln!(
            "warning: dropped {}; over the {} measured positions of the data they move the points by up to {:.3} mm, which the exported URDF does not have",
            dropped.join(", "),
            samples.len(),
            max * 1e3
        );
    }
    Ok(ExitCode::SUCCESS)
}
