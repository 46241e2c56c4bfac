//! How `armcomp demo` hands out its tables: text or JSON on stdout, optionally an HTML report.

use std::path::Path;

use armcomp_repro::demos::Table;

/// Prints `tables` (JSON with `json`) and writes the HTML report when asked.
pub fn emit(tables: &[Table], json: bool, report: Option<&Path>) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(tables)?);
    } else {
        for t in tables {
            print!("{t}");
        }
    }
    if let Some(dir) = report {
        let page = armcomp_repro::demos::report::write(dir, tables)?;
        eprintln!("wrote {}", page.display());
    }
    Ok(())
}
