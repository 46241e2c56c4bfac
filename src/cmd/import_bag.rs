use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_bag::{Bag, Clock, ImportSettings, import_bag};
use armcomp_core::data::measurement::write_csv;
use armcomp_core::model::units::{AngleUnit, LengthUnit, Units};
use armcomp_core::support::io::write_atomic;

#[derive(clap::Args)]
pub struct Args {
    /// The ROS 2 bag: an MCAP (.mcap) or sqlite3 (.db3) file, or the folder `ros2 bag record`
    /// wrote (its files read in order).
    #[arg(long)]
    bag: PathBuf,
    /// The robot file whose joints the joint states name (a bare URDF too).
    #[arg(long)]
    robot: PathBuf,
    /// The sensor_msgs/msg/JointState topic.
    #[arg(long, default_value = "/joint_states")]
    joint_topic: String,
    /// The tracker's topic: geometry_msgs/msg/PoseStamped, geometry_msgs/msg/TransformStamped
    /// or tf2_msgs/msg/TFMessage (`/tf`, with --parent-frame and --child-frame).
    #[arg(long)]
    measurement_topic: String,
    /// The tracker's frame: a transform's parent, a pose's frame_id (checked when given).
    #[arg(long)]
    parent_frame: Option<String>,
    /// The tracked body's frame: a transform's child_frame_id (checked when given).
    #[arg(long)]
    child_frame: Option<String>,
    /// A joint of the joint states that is not the robot's (a gripper's), left out; repeat
    /// for several.
    #[arg(long = "ignore-joint", value_name = "NAME")]
    ignored_joints: Vec<String>,
    /// The robot's point the tracker measures (default: the robot file's first marker).
    #[arg(long)]
    point: Option<String>,
    /// The shortest rest of the joints that makes a static posture, in seconds.
    #[arg(long, default_value_t = 1.0)]
    rest_s: f64,
    /// The speed under which a joint rests, in deg/s (mm/s for a prismatic joint), from
    /// consecutive positions.
    #[arg(long, default_value_t = 0.5)]
    motion_threshold_deg_s: f64,
    /// The largest clock offset between the tracker and the joint states accepted, in seconds;
    /// an import whose estimated offset is larger is refused.
    #[arg(long, default_value_t = 5.0)]
    max_clock_offset_s: f64,
    /// The time of a sample: its message's header stamp, or when the recorder received it.
    #[arg(long, default_value = "header", value_parser = ["header", "receive"])]
    clock: String,
    /// The length unit of the output's columns (m, cm, mm, in); default: the robot file's.
    #[arg(long)]
    length_unit: Option<String>,
    /// The angle unit of the output's joint columns (rad, deg); default: the robot file's.
    #[arg(long)]
    angle_unit: Option<String>,
    /// Print the import's report (postures, clock offset, dropped samples) as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Output measurement CSV (written atomically, units in its header): one row per static
    /// posture.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot)?;
    let mut units = robot.units();
    if let Some(u) = &args.length_unit {
        units.length =
            LengthUnit::parse(u).ok_or_else(|| anyhow::anyhow!("--length-unit `{u}`: expected m, cm, mm or in"))?;
    }
    if let Some(u) = &args.angle_unit {
        units.angle = AngleUnit::parse(u).ok_or_else(|| anyhow::anyhow!("--angle-unit `{u}`: expected rad or deg"))?;
    }
    let bag = Bag::open(&args.bag)?;
    let files: Vec<&std::path::Path> = bag.files.iter().map(|(p, _)| p.as_path()).collect();
    super::check_output(&args.out, &robot, &files)?;
    let settings = ImportSettings {
        parent_frame: args.parent_frame,
        child_frame: args.child_frame,
        ignored_joints: args.ignored_joints,
        point: args.point,
        rest_time: args.rest_s,
        motion_threshold: args.motion_threshold_deg_s.to_radians(),
        max_clock_offset: args.max_clock_offset_s,
        clock: if args.clock == "receive" {
            Clock::Receive
        } else {
            Clock::Header
        },
        max_record_bytes: super::input_limits().max_bytes,
        ..ImportSettings::new(&args.joint_topic, &args.measurement_topic)
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("reading the bag, pass {msg}/2 {bar:30} {percent}%  {elapsed}")
            .expect("the template is valid"),
    );
    let import = import_bag(&bag, &robot, &settings, &mut |p| {
        bar.set_length(p.position.total);
        bar.set_position(p.position.done);
        bar.set_message(p.pass.to_string());
    });
    bar.finish_and_clear();
    let import = import?;
    write_atomic(&args.out, write_csv(&import.set, robot.tree(), units).as_bytes())?;
    let r = &import.report;
    if args.json {
        println!("{}", serde_json::to_string_pretty(r)?);
    } else {
        print_report(r, units);
    }
    eprintln!(
        "wrote {} static postures to {}",
        import.set.samples.len(),
        args.out.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn print_report(r: &armcomp_bag::ImportReport, units: Units) {
    let lu = units.length.symbol();
    println!(
        "read {} joint states and {} tracker messages ({} messages of other topics skipped)",
        r.joint_messages, r.measurement_messages, r.other_messages
    );
    let o = &r.clock_offset;
    println!(
        "clock offset: the tracker stamps {:+.4} s ± {:.4} s after the joints (from {} blocks of motion, correlation \
         {:.3}); applied",
        o.seconds, o.std, o.blocks, o.correlation
    );
    println!("posture  start[s]  rest[s]  joint samples  tracker samples  repeatability[{lu}]");
    for (k, p) in r.postures.iter().enumerate() {
        let rep = p
            .repeatability
            .map_or("-".to_string(), |v| format!("{:.4}", units.len_out(v)));
        println!(
            "{k:>7}  {:>8.2}  {:>7.2}  {:>13}  {:>15}  {rep:>17}",
            p.start, p.duration, p.joint_samples, p.tracker_samples
        );
    }
    for (reason, n) in &r.dropped {
        println!("dropped {n} {}", reason.describe());
    }
}
