use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::io::write_atomic;

#[derive(clap::Args)]
pub struct Args {
    /// Robot or model file (TOML, JSON) whose kinematics is `type = "urdf"`; its identified
    /// joint origins and axes are written out.
    #[arg(long)]
    model: PathBuf,
    /// Output URDF (written atomically; lengths in m, angles in rad). The model's URDF with
    /// every joint's origin and axis replaced and everything else kept.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = armcomp::load_robot(&args.model)?;
    let (source, text) = armcomp_urdf::calibrated_urdf(&robot)?;
    super::check_output(&args.out, &robot, &[&source])?;
    write_atomic(&args.out, text.as_bytes())?;
    eprintln!(
        "wrote {} ({} joints of {} with identified origins and axes)",
        args.out.display(),
        robot.tree().joints().len(),
        source.display()
    );
    Ok(ExitCode::SUCCESS)
}
