use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::support::io::{check_output, write_atomic};

#[derive(clap::Args)]
pub struct Args {
    /// Write the schema to this file (atomically) instead of standard output.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let text = armcomp_api::schema_text();
    match args.out {
        Some(p) => {
            check_output(&p, &[])?;
            write_atomic(&p, text.as_bytes())?
        }
        None => print!("{text}"),
    }
    Ok(ExitCode::SUCCESS)
}
