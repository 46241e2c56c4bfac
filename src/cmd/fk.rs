use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use armcomp_core::Robot;
use nalgebra::UnitQuaternion;

#[derive(clap::Args)]
pub struct Args {
    /// Robot file (TOML, or JSON by extension), or a bare URDF.
    #[arg(long)]
    robot: PathBuf,
    /// Joint values, comma-separated: one per independent joint in file order, or
    /// `name=value` pairs (joints not named stay at zero); revolute in rad (deg with --deg),
    /// prismatic in m.
    #[arg(long, allow_hyphen_values = true)]
    q: String,
    /// Revolute values are in degrees.
    #[arg(long)]
    deg: bool,
    /// Print JSON (metres): {"points": {name: [x, y, z]}, "tool": {"position": [..], "quaternion": [w, x, y, z]}}.
    #[arg(long)]
    json: bool,
}

/// Parses `--q` into SI joint values for `robot`: one value per independent joint in order
/// (`0.1,0.2,...`), or `name=value` pairs (`shoulder=0.3,elbow=-1.2`) with the joints not
/// named at zero.
pub fn parse_q(robot: &Robot, text: &str, deg: bool) -> anyhow::Result<Vec<f64>> {
    let tree = robot.tree();
    let names = tree.coordinate_names();
    let number = |what: &str, part: &str| -> anyhow::Result<f64> {
        let v: f64 = part
            .trim()
            .parse()
            .with_context(|| format!("--q {what} (`{}`) is not a number", part.trim()))?;
        if !v.is_finite() {
            bail!("--q {what} is not finite");
        }
        Ok(v)
    };
    // Coordinate `i`'s value in SI units.
    let si = |i: usize, v: f64| {
        let prismatic = tree.coordinate_is_prismatic().get(i).copied().unwrap_or(false);
        if deg && !prismatic { v.to_radians() } else { v }
    };
    let parts: Vec<&str> = text.split(',').collect();
    let q = if parts.iter().any(|p| p.contains('=')) {
        let mut named = Vec::with_capacity(parts.len());
        for part in parts {
            let Some((name, v)) = part.split_once('=') else {
                bail!(
                    "--q mixes `name=value` pairs with a plain value (`{part}`); give all joints by name or all by position"
                );
            };
            let name = name.trim();
            named.push((name, number(&format!("value of `{name}`"), v)?));
        }
        // Joints not named stay at zero.
        let q = tree.coordinates_by_name(named).context("--q")?;
        q.into_iter()
            .enumerate()
            .map(|(i, v)| v.map_or(0.0, |v| si(i, v)))
            .collect()
    } else {
        let q = parts
            .iter()
            .enumerate()
            .map(|(i, part)| Ok(si(i, number(&format!("value {}", i + 1), part)?)))
            .collect::<anyhow::Result<Vec<f64>>>()?;
        if q.len() != tree.nq() {
            bail!(
                "--q has {} values but the robot has {} joints: {}",
                q.len(),
                tree.nq(),
                names.join(", ")
            );
        }
        q
    };
    for (i, lim) in tree.coordinate_limits().iter().enumerate() {
        if let Some(l) = lim
            && (q[i] < l.lower - 1e-12 || q[i] > l.upper + 1e-12)
        {
            eprintln!(
                "warning: joint `{}` = {} is outside its limits [{}, {}] (SI units)",
                names[i], q[i], l.lower, l.upper
            );
        }
    }
    Ok(q)
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot)?;
    let q = parse_q(&robot, &args.q, args.deg)?;
    let frames = robot.forward(&q)?;
    let tree = robot.tree();
    let tool = frames.point[robot.tool()];
    let quat: UnitQuaternion<f64> = tool.rotation;
    if args.json {
        let mut points = serde_json::Map::new();
        for (i, p) in tree.points().iter().enumerate() {
            let v = frames.point[i].translation.vector;
            points.insert(p.name.clone(), serde_json::json!([v.x, v.y, v.z]));
        }
        let t = tool.translation.vector;
        let out = serde_json::json!({
            "points": points,
            "tool": { "position": [t.x, t.y, t.z], "quaternion": [quat.w, quat.i, quat.j, quat.k] },
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        println!("{:<16} {:>12} {:>12} {:>12}", "point", "x [m]", "y [m]", "z [m]");
        for (i, p) in tree.points().iter().enumerate() {
            let v = frames.point[i].translation.vector;
            println!("{:<16} {:>12.6} {:>12.6} {:>12.6}", p.name, v.x, v.y, v.z);
        }
        println!(
            "tool `{}` orientation (quaternion w, x, y, z): {:.9}, {:.9}, {:.9}, {:.9}",
            tree.points()[robot.tool()].name,
            quat.w,
            quat.i,
            quat.j,
            quat.k
        );
    }
    Ok(ExitCode::SUCCESS)
}
