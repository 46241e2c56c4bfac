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
    let schema = armcomp_api::robot_schema();
    let mut all = Vec::new();
    for f in &args.files {
        let armcomp_api::Validation {
            problems,
            not_loaded,
            loaded,
            warnings,
        } = armcomp_api::check_file(f, &schema, super::input_limits());
        for w in &warnings {
            eprintln!("warning: {w}");
        }
        // Not a problem of the file: the user has not allowed its code to run.
        for n in &not_loaded {
            eprintln!(
                "note: {n}; its plugin was not loaded, so its config was not checked against the library's schema"
            );
        }
        if !args.json {
            if problems.is_empty() {
                println!("{}: ok", f.display());
            }
            // Loading ran the library's code: the user sees which libraries that was.
            for lib in &loaded {
                println!(
                    "{}: loaded and checked the plugin library {}",
                    f.display(),
                    lib.display()
                );
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
