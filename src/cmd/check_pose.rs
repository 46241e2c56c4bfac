use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::CollisionModel;

#[derive(clap::Args)]
pub struct Args {
    /// Robot file (TOML, JSON) with link shapes and fixtures, or a bare URDF (its collision
    /// elements).
    #[arg(long)]
    robot: PathBuf,
    /// Joint values as for `fk`: by position or as `name=value` pairs; rad (deg with --deg), m.
    #[arg(long, allow_hyphen_values = true)]
    q: String,
    /// Revolute values are in degrees.
    #[arg(long)]
    deg: bool,
    /// Print JSON (metres): {"collides", "pairs_checked", "contacts": [{"first", "second",
    /// "fixture", "distance", "point_first", "point_second"}]}.
    #[arg(long)]
    json: bool,
}

/// Exit code 0: no collision; 2: collisions found; 1: error.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot)?;
    let q = super::fk::parse_q(&robot, &args.q, args.deg)?;
    let model = CollisionModel::new(robot.tree(), robot.collision());
    let mut ws = model.workspace();
    let contacts = model.check(&q, &mut ws);
    if args.json {
        let out = serde_json::json!({
            "collides": !contacts.is_empty(),
            "pairs_checked": model.pair_count(),
            "contacts": contacts,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else if contacts.is_empty() {
        println!("no collision ({} shape pairs checked)", model.pair_count());
    } else {
        println!(
            "{} collision(s) ({} shape pairs checked):",
            contacts.len(),
            model.pair_count()
        );
        for c in &contacts {
            let what = if c.distance <= 0.0 {
                format!("overlap {:.3} mm", -c.distance * 1e3)
            } else {
                format!("{:.3} mm apart, inside the margin", c.distance * 1e3)
            };
            let p = c.point_first;
            println!(
                "  {} – {}{}: {what}, at ({:.4}, {:.4}, {:.4}) m",
                c.first,
                c.second,
                if c.fixture { " (fixture)" } else { "" },
                p.x,
                p.y,
                p.z
            );
        }
    }
    Ok(if contacts.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(2)
    })
}
