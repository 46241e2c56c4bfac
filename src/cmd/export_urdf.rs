use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use armcomp_core::support::io::write_atomic;

use super::read_measurements;

#[derive(clap::Args)]
pub struct Args {
    /// Robot or model file (TOML, JSON) whose kinematics is `type = "urdf"`; its identified
    /// joint origins are written out.
    #[arg(long)]
    model: PathBuf,
    /// Output URDF (written atomically; lengths in m, angles in rad): the model's URDF with the
    /// origin and axis of every identified joint replaced and every other byte kept.
    #[arg(long)]
    out: PathBuf,
    /// Export the rigid geometry of a model whose error models or fitted predictor URDF cannot
    /// express, dropping them; needs `--data` to state how far that moves the measured points.
    #[arg(long, requires = "data")]
    rigid_only: bool,
    /// Measurement CSV whose poses measure what `--rigid-only` drops.
    #[arg(long)]
    data: Option<PathBuf>,
}

/// Refuses an export of `model` that would drop the models URDF cannot express, unless
/// `rigid_only` asks for that.
pub fn refuse_inexpressible(model: &std::path::Path, dropped: &[String], rigid_only: bool) -> anyhow::Result<()> {
    if !dropped.is_empty() && !rigid_only {
        bail!(
            "{}: URDF cannot express {}; the exported URDF would not be this model. Pass --rigid-only --data <measurements.csv> to export the rigid geometry anyway and see how far the dropped models move the measured points",
            model.display(),
            dropped.join(", ")
        );
    }
    Ok(())
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.model)?;
    let dropped = armcomp_api::ops::export_urdf::inexpressible(&robot);
    refuse_inexpressible(&args.model, &dropped, args.rigid_only)?;
    let urdf = armcomp_urdf::calibrated_urdf(&robot)?;
    let data: Vec<&std::path::Path> = args.data.iter().map(|p| p.as_path()).collect();
    super::check_output(&args.out, &robot, &[&[urdf.source.as_path()], data.as_slice()].concat())?;
    let deviation = match (&args.data, dropped.is_empty()) {
        (Some(data), false) => {
            let set = read_measurements(&robot, data, None)?;
            let max = armcomp_api::ops::export_urdf::rigid_deviation(&robot, &set.samples)?;
            Some((max, set.samples.len()))
        }
        _ => None,
    };
    write_atomic(&args.out, urdf.text.as_bytes())?;
    eprintln!(
        "wrote {} from {} (every byte outside the rows below kept):",
        args.out.display(),
        urdf.source.display()
    );
    let rows = armcomp_api::ops::export_urdf::summary(&robot, &urdf, &dropped);
    let width = |k: usize| rows.iter().map(|r| r[k].chars().count()).max().unwrap_or(0);
    let (w0, w1) = (width(0), width(1));
    for [status, item, details] in &rows {
        eprintln!("  {status:<w0$}  {item:<w1$}  {details}");
    }
    if let Some((max, n)) = deviation {
        eprintln!(
            "warning: dropped {}; over the {n} measured positions of the data they move the points by up to {:.3} mm, which the exported URDF does not have",
            dropped.join(", "),
            max * 1e3
        );
    }
    Ok(ExitCode::SUCCESS)
}
