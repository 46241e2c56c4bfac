use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct Args {
    /// Robot files (TOML, or JSON by extension).
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Print the problems as JSON: [{"file", "line", "path", "message"}, ...].
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let schema = armcomp::robot_schema();
    let mut all = Vec::new();
    for f in &args.files {
        let problems = armcomp::validate_file(f, &schema);
        if !args.json {
            if problems.is_empty() {
                println!("{}: ok", f.display());
            }
            for p in &problems {
                println!("{p}");
            }
        }
        all.extend(problems);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&all)?);
    }
    Ok(if all.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
