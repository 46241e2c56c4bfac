use std::process::ExitCode;

use anyhow::bail;
use armcomp_core::Robot;
use armcomp_repro::twins::{TWINS, Twin};

#[derive(clap::Args)]
pub struct Args {
    /// Which twin: `rock-drill` (default), `industrial`, or real data: `agile-justin`, `talos`
    /// (learning curves on TALOS' measurements).
    #[arg(default_value = "rock-drill")]
    twin: String,
    /// Seed of every random draw of the protocol; the same seed gives the same tables.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print the tables as JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Also write an HTML page with the tables into this folder.
    #[arg(long)]
    report: Option<std::path::PathBuf>,
    /// rock-drill: draw the training poses at random from the whole grid instead of group by
    /// group (one setting of the telescopic joints after another) as the paper collected them.
    #[arg(long)]
    random_poses: bool,
    /// rock-drill: run the protocol on this many consecutive seeds from `--seed` and print how
    /// each row spreads over them and on how many seeds each claim held.
    #[arg(long)]
    seeds: Option<usize>,
    /// agile-justin: folds of the cross-validation (0 skips it).
    #[arg(long, default_value_t = 5)]
    folds: usize,
    /// agile-justin: leave out the residual predictor over the calibrated elastic model.
    #[arg(long)]
    no_predictor: bool,
    /// agile-justin: also the paper's leave-one-out analysis (full model without one parameter
    /// group at a time) on the fixed split.
    #[arg(long)]
    leave_one_out: bool,
    /// agile-justin: also `armcomp diagnose` from the frames-only model, with at most this many
    /// effects (0 skips it; minutes per effect).
    #[arg(long, default_value_t = 0)]
    diagnose_steps: usize,
    /// agile-justin: instead of the table, the held-out error against the number of training
    /// poses (20 … 250) for the poses `armcomp plan` chooses and for random subsets (the
    /// `talos` demo always shows these).
    #[arg(long)]
    learning_curve: bool,
    /// Learning curves: how the tool chooses (d-optimal, a-optimal or uncertainty).
    #[arg(long, default_value = "uncertainty")]
    curve_method: armcomp_core::analysis::design::Criterion,
    /// Learning curves: random subsets per size.
    #[arg(long, default_value_t = 10)]
    draws: usize,
    /// talos: the robot file (default: robots/talos-left-arm.toml, from the repository root).
    #[arg(long)]
    robot: Option<std::path::PathBuf>,
    /// talos: the measurements (default: data/talos-left-arm/measurements.csv).
    #[arg(long)]
    data: Option<std::path::PathBuf>,
}

/// The work of one random draw of the learning curves: a fit per size of every curve, some
/// seconds.
const DRAW_FLOPS: f64 = 3e9;

/// Joint configurations to show: all zero, the middle of the limits, and the upper limits.
fn configurations(robot: &Robot) -> Vec<(&'static str, Vec<f64>)> {
    let lims = robot.tree().coordinate_limits();
    let pick = |f: fn(f64, f64) -> f64| lims.iter().map(|l| l.map_or(0.0, |l| f(l.lower, l.upper))).collect();
    vec![
        ("zero", vec![0.0; lims.len()]),
        ("mid-range", pick(|a, b| 0.5 * (a + b))),
        ("upper limits", pick(|_, b| b)),
    ]
}

fn describe(twin: &Twin) -> anyhow::Result<Robot> {
    let robot = twin.robot()?;
    let tree = robot.tree();
    println!(
        "== {} ({}): {}",
        robot.name(),
        twin.path,
        robot.description().unwrap_or("")
    );
    println!(
        "   {} joints, {} identifiable chain parameters, {} points",
        tree.nq(),
        robot.chain_params().len(),
        tree.points().len()
    );
    for (i, name) in tree.coordinate_names().iter().enumerate() {
        let prismatic = tree.coordinate_is_prismatic()[i];
        let (scale, unit) = if prismatic {
            (1000.0, "mm")
        } else {
            (180.0 / std::f64::consts::PI, "deg")
        };
        match tree.coordinate_limits()[i] {
            Some(l) => println!(
                "   {name:<6} {:>9.1} .. {:>7.1} {unit}",
                l.lower * scale,
                l.upper * scale
            ),
            None => println!("   {name:<6} unlimited"),
        }
    }
    println!("   tool position [mm]:");
    for (label, q) in configurations(&robot) {
        let p = robot.forward(&q)?.point[robot.tool()].translation.vector * 1000.0;
        println!("   {label:<14} {:>10.2} {:>10.2} {:>10.2}", p.x, p.y, p.z);
    }
    Ok(robot)
}

/// `--seeds N` on the rock drill.
fn sweep(config: &armcomp_repro::demos::rock_drill::Config, n: usize, args: &Args) -> anyhow::Result<ExitCode> {
    if args.report.is_some() {
        bail!("--report draws one seed's run; leave out --seeds, or --report");
    }
    let bar = crate::progress::bar(Some(n as u64), "seeds {bar:30} {pos}/{len}  {msg}");
    let sweep = armcomp_repro::demos::rock_drill::sweep(config, n, &|seed| {
        bar.set_message(format!("seed {seed} done"));
        bar.inc(1);
    });
    bar.finish_and_clear();
    let sweep = sweep?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&sweep)?);
    } else {
        print!("{sweep}");
    }
    Ok(ExitCode::SUCCESS)
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if args.seeds.is_some() && args.twin != "rock-drill" {
        bail!("--seeds runs the rock-drill demo only, not `{}`", args.twin);
    }
    if args.twin != "talos" && (args.robot.is_some() || args.data.is_some()) {
        bail!(
            "--robot and --data go with the talos demo; the `{}` demo runs its built-in twin",
            args.twin
        );
    }
    if let (Some(dir), None) = (&args.report, args.seeds) {
        armcomp_repro::demos::report::check(dir)?;
    }
    match args.twin.as_str() {
        "rock-drill" => {
            if !args.json {
                describe(Twin::get("rock-drill").expect("built in"))?;
            }
            let config = armcomp_repro::demos::rock_drill::Config {
                grouped: !args.random_poses,
                ..armcomp_repro::demos::rock_drill::Config::paper(args.seed)
            };
            if let Some(n) = args.seeds {
                return sweep(&config, n, &args);
            }
            let table = armcomp_repro::demos::rock_drill::run(&config)?;
            super::demo_output::emit(&[table], args.json, args.report.as_deref())?;
        }
        "industrial" => {
            if args.json {
                let table =
                    armcomp_repro::demos::industrial::run(&armcomp_repro::demos::industrial::Config::paper(args.seed))?;
                super::demo_output::emit(&[table], true, args.report.as_deref())?;
                return Ok(ExitCode::SUCCESS);
            }
            let mdh = describe(Twin::get("industrial").expect("built in"))?;
            // The same arm in three conventions: report how far apart their tools are.
            for other in ["industrial-dh", "industrial-poe"] {
                let robot = Twin::get(other).expect("built in").robot()?;
                let mut worst: f64 = 0.0;
                for (_, q) in configurations(&mdh) {
                    let a = mdh.forward(&q)?.point[mdh.tool()];
                    let b = robot.forward(&q)?.point[robot.tool()];
                    worst = worst.max((a.translation.vector - b.translation.vector).norm());
                }
                println!("   {other}: tool differs from the MDH form by at most {:.3e} m", worst);
            }
            let table =
                armcomp_repro::demos::industrial::run(&armcomp_repro::demos::industrial::Config::paper(args.seed))?;
            super::demo_output::emit(&[table], false, args.report.as_deref())?;
        }
        "agile-justin" | "talos" if args.learning_curve || args.twin == "talos" => {
            if args.draws == 0 {
                bail!("--draws 0: the random subsets the tool's choice is compared with need at least 1 draw per size");
            }
            armcomp_core::support::limits::check("--draws", args.draws, "draws", &|d| {
                armcomp_core::support::limits::Cost::per_unit(d, 0.0, DRAW_FLOPS)
            })?;
            let opts = super::demo_curve::CurveParams {
                json: args.json,
                seed: args.seed,
                criterion: args.curve_method,
                draws: args.draws,
                report: args.report,
            };
            return if args.twin == "talos" {
                super::demo_curve::talos(&opts, args.robot.as_deref(), args.data.as_deref())
            } else {
                super::demo_curve::agile_justin(&opts)
            };
        }
        "agile-justin" => {
            return super::demo_justin::run(&super::demo_justin::JustinParams {
                json: args.json,
                folds: args.folds,
                seed: args.seed,
                no_predictor: args.no_predictor,
                leave_one_out: args.leave_one_out,
                diagnose_steps: args.diagnose_steps,
                report: args.report,
            });
        }
        other => bail!(
            "unknown twin `{other}`; demos: rock-drill, industrial, agile-justin, talos (robot files: {})",
            TWINS.iter().map(|t| t.path).collect::<Vec<_>>().join(", ")
        ),
    }
    Ok(ExitCode::SUCCESS)
}
