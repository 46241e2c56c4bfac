use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;

#[derive(clap::Args)]
pub struct Args {
    /// Also load this run-time plugin library (repeatable) and list its types; without an
    /// extension the platform's naming applies (`libNAME.so`, `libNAME.dylib`, `NAME.dll`).
    #[arg(long)]
    library: Vec<PathBuf>,
    /// Print JSON: [{"type": .., "role": .., "doc": .., "diagnosis_candidate": ..}, ...].
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    for lib in &args.library {
        armcomp_sdk::load_library(lib).with_context(|| format!("--library {}", lib.display()))?;
    }
    let plugins = armcomp_api::plugins();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&armcomp_api::registry::plugins_json())?
        );
    } else {
        let width = plugins.iter().map(|p| p.type_name.len()).max().unwrap_or(0);
        for p in &plugins {
            let role = p.role.field();
            let cand = if p.diagnosis_candidate {
                " [diagnosis candidate]"
            } else {
                ""
            };
            println!("{:<12} {:<width$}  {}{}", role, p.type_name, p.doc, cand);
        }
    }
    Ok(ExitCode::SUCCESS)
}
