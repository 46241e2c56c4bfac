use std::process::ExitCode;

#[derive(clap::Args)]
pub struct Args {
    /// Print JSON: [{"type": .., "role": .., "doc": .., "diagnosis_candidate": ..}, ...].
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let plugins = armcomp::plugins();
    if args.json {
        let list: Vec<_> = plugins
            .iter()
            .map(|p| {
                serde_json::json!({
                    "type": p.type_name,
                    "role": p.role,
                    "doc": p.doc,
                    "diagnosis_candidate": p.diagnosis_candidate,
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&list)?);
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
