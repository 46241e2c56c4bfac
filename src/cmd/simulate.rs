use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::algorithms::simulate::{Contact, Ground};
use armcomp_core::data::measurement::{parse_poses, write_csv, write_csv_with_sensors};
use armcomp_core::support::io::write_atomic;

#[derive(clap::Args)]
pub struct Args {
    /// The truth robot file (its error models carry the true values), or a bare URDF.
    #[arg(long)]
    robot: PathBuf,
    /// Number of poses to draw inside the joint limits (ignored with --poses).
    #[arg(long, default_value_t = 100, value_parser = super::at_least_one)]
    n: usize,
    /// How to draw poses: sobol, halton, random or grid.
    #[arg(long, default_value = "sobol")]
    sampler: String,
    /// Read the poses from this CSV (joint columns with units in the header) instead of drawing them.
    #[arg(long)]
    poses: Option<PathBuf>,
    /// Standard deviation of the measurement noise per axis, in mm.
    #[arg(long, default_value_t = 0.0)]
    noise_mm: f64,
    /// Standard deviation (deg) of the base's tilt about its x and y axes, drawn anew at every
    /// pose (or station, `--tilt-per station`); the robot file's sensors (`[[sensors]]`) read it
    /// (a link's with the bending below it, each with its mounting and noise) and their columns
    /// are written. With a `measured_tilt` on a base sensor the tilt turns the measured points
    /// too (a base rocking under a tracker on the ground), else only the loads.
    #[arg(long, default_value_t = 0.0)]
    tilt_deg: f64,
    /// Draw the tilt anew at every `row` (a carrier moving between measurements) or once per
    /// `station` (a carrier parked on other ground for each set-up).
    #[arg(long, default_value = "row", value_parser = ["row", "station"])]
    tilt_per: String,
    /// Seed for pose sampling and noise; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// A fixed point the tool is put into from --n configurations each (found by inverse
    /// kinematics), as `name=x,y,z` in mm in the measurement frame; repeat for several. For a
    /// truth that measures positions (`kind = "point"`), its rows follow the tracker's: mixed
    /// data.
    #[arg(long = "fixed-point", value_name = "NAME=X,Y,Z")]
    fixed_points: Vec<String>,
    /// A plane the tool is pressed on from --n configurations each (found by inverse
    /// kinematics; flush when the truth constrains tilts), as `name=x,y,z,roll,pitch,yaw` (mm
    /// and deg, measurement frame; its normal the frame's z axis); repeat for several. For a
    /// truth that measures positions or poses, its rows follow the tracker's: mixed data.
    #[arg(long = "plane", value_name = "NAME=X,Y,Z,ROLL,PITCH,YAW")]
    planes: Vec<String>,
    /// Half the side of the square on each plane the contacts are drawn in, in mm.
    #[arg(long, default_value_t = 80.0, value_parser = super::positive)]
    spread_mm: f64,
    /// Standard deviation of the joint encoders' noise, in degrees (fixed points, planes).
    #[arg(long, default_value_t = 0.0)]
    joint_noise_deg: f64,
    /// Measure from this many stations (total-station set-ups), each its own measurement
    /// frame drawn from --seed around the truth's (the first is the truth's; every other turned
    /// about the vertical at random, tilted by up to 2 deg and moved by up to 2 m): the poses in
    /// as many consecutive blocks, and a `station` column (`st1`, `st2`, ...). Default: the
    /// truth's stations, or one.
    #[arg(long, value_parser = super::at_least_one)]
    stations: Option<usize>,
    /// A ground the robot stands on, measured from a station of its own, as
    /// `name=tilt,rocking` in degrees: the base tilted by `tilt` about a horizontal axis drawn
    /// from --seed, and rocking from pose to pose about its x and y axes with a standard
    /// deviation of `rocking` (soft ground; 0 or left out on firm ground). Repeat for several
    /// (e.g. `--ground flat=0 --ground slope=3,0.005 --ground soft=0.5,0.03`): the poses in as
    /// many consecutive blocks, the station column naming the ground. The truth's sensors read
    /// it, as for --tilt-deg, which it replaces.
    #[arg(long = "ground", value_name = "NAME=TILT[,ROCKING]", conflicts_with_all = ["stations", "tilt_deg", "tilt_per"])]
    grounds: Vec<String>,
    /// Output CSV (written atomically; in the robot file's units).
    #[arg(long)]
    out: PathBuf,
}

/// `name=tilt[,rocking]` (deg) → the name and the ground (rad).
fn ground(text: &str) -> anyhow::Result<(String, Ground)> {
    let parsed = text.split_once('=').and_then(|(name, v)| {
        let v: Vec<f64> = v.split(',').map(|c| c.trim().parse().ok()).collect::<Option<_>>()?;
        let name = name.trim();
        let ok = matches!(v.len(), 1 | 2) && v.iter().all(|x| x.is_finite() && *x >= 0.0);
        (ok && !name.is_empty() && !name.contains(',')).then(|| {
            let ground = Ground {
                tilt: v[0].to_radians(),
                rocking: v.get(1).copied().unwrap_or(0.0).to_radians(),
            };
            (name.to_string(), ground)
        })
    });
    parsed.ok_or_else(|| {
        anyhow::anyhow!(
            "--ground `{text}`: expected name=tilt,rocking in degrees, both zero or more, e.g. soft=0.5,0.03 (the \
             rocking may be left out: slope=3)"
        )
    })
}

/// `name=x,y,z` (mm) → the name and the point (m).
fn fixed_point(text: &str) -> anyhow::Result<(String, nalgebra::Vector3<f64>)> {
    let parsed = text.split_once('=').and_then(|(name, xyz)| {
        let v: Vec<f64> = xyz.split(',').map(|c| c.trim().parse().ok()).collect::<Option<_>>()?;
        (v.len() == 3 && v.iter().all(|x| x.is_finite()) && !name.trim().is_empty())
            .then(|| (name.trim().to_string(), nalgebra::Vector3::new(v[0], v[1], v[2]) * 1e-3))
    });
    parsed.ok_or_else(|| anyhow::anyhow!("--fixed-point `{text}`: expected name=x,y,z in mm, e.g. hole_0=450,-25,120"))
}

/// `name=x,y,z,roll,pitch,yaw` (mm, deg) → the name and the plane's pose (m, rad).
fn plane(text: &str, spread_mm: f64) -> anyhow::Result<(String, Contact)> {
    let parsed = text.split_once('=').and_then(|(name, v)| {
        let v: Vec<f64> = v.split(',').map(|c| c.trim().parse().ok()).collect::<Option<_>>()?;
        (v.len() == 6 && v.iter().all(|x| x.is_finite()) && !name.trim().is_empty()).then(|| {
            let pose = armcomp_core::model::geom::xyz_rpy(
                [v[0] * 1e-3, v[1] * 1e-3, v[2] * 1e-3],
                [v[3].to_radians(), v[4].to_radians(), v[5].to_radians()],
            );
            (
                name.trim().to_string(),
                Contact::Plane {
                    pose,
                    spread: spread_mm * 1e-3,
                },
            )
        })
    });
    parsed.ok_or_else(|| {
        anyhow::anyhow!(
            "--plane `{text}`: expected name=x,y,z,roll,pitch,yaw in mm and deg, e.g. table=500,0,150,180,0,0"
        )
    })
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mut truth = super::load_robot(&args.robot)?;
    let planar = truth.measures_planes();
    if truth.measures_fixed_points() || planar {
        let (flag, given) = if planar {
            ("--plane name=x,y,z,roll,pitch,yaw (mm, deg", &args.planes)
        } else {
            ("--fixed-point name=x,y,z (mm", &args.fixed_points)
        };
        if given.is_empty() {
            anyhow::bail!(
                "{} measures without an instrument: name where with {flag}, measurement frame)",
                args.robot.display()
            );
        }
        super::check_output(&args.out, &truth, &[])?;
        let contacts = if planar {
            args.planes
                .iter()
                .map(|t| plane(t, args.spread_mm))
                .collect::<anyhow::Result<Vec<_>>>()?
        } else {
            args.fixed_points
                .iter()
                .map(|t| fixed_point(t).map(|(name, p)| (name, Contact::FixedPoint(p))))
                .collect::<anyhow::Result<Vec<_>>>()?
        };
        let params = armcomp_core::algorithms::simulate::FixedPointParams {
            per_point: args.n,
            joint_noise_std: args.joint_noise_deg.to_radians(),
            seed: args.seed,
        };
        let set = armcomp_core::algorithms::simulate::simulate_contacts(&truth, &contacts, params)?;
        write_atomic(&args.out, write_csv(&set, truth.tree(), truth.units()).as_bytes())?;
        eprintln!(
            "wrote {} configurations at {} {} to {} (joint noise {} deg, seed {})",
            set.samples.len(),
            contacts.len(),
            if planar { "planes" } else { "fixed points" },
            args.out.display(),
            args.joint_noise_deg,
            args.seed
        );
        return Ok(ExitCode::SUCCESS);
    }
    let poses_file: Vec<&std::path::Path> = args.poses.iter().map(|p| p.as_path()).collect();
    super::check_output(&args.out, &truth, &poses_file)?;
    let poses = match &args.poses {
        Some(p) => {
            let text = armcomp_core::support::io::read_text(p, super::input_limits())?;
            parse_poses(&text, p, &truth.csv_layout())?
        }
        None => armcomp_api::ops::simulate::draw_poses(&truth, &args.sampler, args.n, args.seed)?,
    };
    let stand = armcomp_api::ops::simulate::Stand {
        stations: args.stations,
        grounds: args
            .grounds
            .iter()
            .map(|g| ground(g))
            .collect::<anyhow::Result<Vec<_>>>()?,
        tilt_deg: args.tilt_deg,
        tilt_per_station: args.tilt_per == "station",
    };
    let mut set = armcomp_api::ops::simulate::run_standing(&mut truth, &poses, args.noise_mm, &stand, args.seed)?;
    // Fixed points or planes named for a truth that measures positions: mixed data, the
    // tracker's rows then the contacts'.
    let contacts = (args.fixed_points.iter())
        .map(|t| fixed_point(t).map(|(name, p)| (name, Contact::FixedPoint(p))))
        .chain(args.planes.iter().map(|t| plane(t, args.spread_mm)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if !contacts.is_empty() {
        let params = armcomp_core::algorithms::simulate::FixedPointParams {
            per_point: args.n,
            joint_noise_std: args.joint_noise_deg.to_radians(),
            seed: args.seed,
        };
        let fixed = armcomp_core::algorithms::simulate::simulate_contacts(&truth, &contacts, params)?;
        let first = set.rows.last().map_or(0, |r| r + 1);
        set.rows.extend(fixed.rows.iter().map(|r| r + first));
        set.samples.extend(fixed.samples);
    }
    for w in &set.warnings {
        eprintln!("warning: {w}");
    }
    let text = write_csv_with_sensors(&set, truth.tree(), truth.units(), truth.sensors());
    write_atomic(&args.out, text.as_bytes())?;
    eprintln!(
        "wrote {} measurements of {} poses{} to {} (noise {} mm per axis, seed {})",
        set.samples.len(),
        poses.len(),
        if contacts.is_empty() {
            String::new()
        } else {
            format!(
                " and {} configurations at {} {} (joint noise {} deg)",
                args.n * contacts.len(),
                contacts.len(),
                match (args.fixed_points.is_empty(), args.planes.is_empty()) {
                    (false, false) => "fixed points and planes",
                    (false, true) => "fixed points",
                    _ => "planes",
                },
                args.joint_noise_deg
            )
        },
        args.out.display(),
        args.noise_mm,
        args.seed
    );
    Ok(ExitCode::SUCCESS)
}
