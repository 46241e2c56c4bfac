//! The demo's HTML report: per table, the rows beside the paper's values and three SVG plots
//! (bars of the rows, error histograms before and after compensation, per-axis errors at the
//! test targets), every file written atomically.

use armcomp_report::html::{escape, page_start};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use armcomp_core::Result;
use armcomp_core::algorithms::evaluate::ErrorStats;
use armcomp_core::support::io::{check_report_folder, write_folder_atomic};

use super::{PaperMetric, Table, plots};
use crate::learning_curve::LearningCurveReport;

/// A learning curve as the report shows it.
#[derive(Debug, Clone)]
pub struct Curve {
    /// The curve.
    pub report: LearningCurveReport,
    /// The held-out statistic shown: `mean` or `rms` (3-D, mm).
    pub metric: &'static str,
    /// A reference value (mm) drawn across the plot, and what it is.
    pub reference: Option<(f64, String)>,
}

impl Curve {
    /// The statistic [`Curve::metric`] names.
    pub fn stat(&self) -> fn(&ErrorStats) -> f64 {
        if self.metric == "rms" {
            |s| s.rms_mm
        } else {
            |s| s.mean_mm
        }
    }
}

/// The file-name stem of a table's plots: its title up to the colon, in lower-case words
/// joined by dashes, numbered so that two tables never share files.
pub fn stem(index: usize, table: &Table) -> String {
    let head = table.title.split(':').next().unwrap_or_default().to_lowercase();
    let words: Vec<&str> = head
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
        .collect();
    format!("{}-{}", index + 1, words.join("-"))
}

/// Whether a file belongs in a demo report folder.
fn is_report_file(name: &str) -> bool {
    name == "index.html" || name.ends_with(".svg")
}

/// Checks, before the demo runs, that `dir` may receive the report: absent, or an earlier
/// report folder (see [`check_report_folder`]).
pub fn check(dir: &Path) -> Result<()> {
    check_report_folder(dir, &is_report_file, &[])
}

/// Writes the folder `dir` with `index.html` and the plots of every table, whole (into a
/// temporary folder, then moved into place), and returns the page's path.
pub fn write(dir: &Path, tables: &[Table]) -> Result<PathBuf> {
    write_page(dir, tables, &[])
}

/// [`write`] with learning curves after the tables: each a table of its sizes and a plot.
pub fn write_page(dir: &Path, tables: &[Table], curves: &[Curve]) -> Result<PathBuf> {
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    let mut html = page_start("armcomp demo", "armcomp demo");
    for (i, t) in tables.iter().enumerate() {
        let stem = stem(i, t);
        let plots: [(&str, &str, plots::Plot); 3] = [
            ("bars", "The table's rows beside the paper's values", plots::bars),
            (
                "histogram",
                "The 3-D errors at the test targets before compensation and with the best pipeline",
                plots::histogram,
            ),
            (
                "axes",
                "The x, y and z errors at every test target before compensation and with the best pipeline",
                plots::per_axis,
            ),
        ];
        let _ = writeln!(
            html,
            "<h2>{}</h2>\n<p>{}. Measurement noise {:.3} mm per axis (mean |z| of the noise alone {:.3} mm).</p>",
            escape(&t.title),
            escape(&t.setup),
            t.noise_mm,
            t.noise_mean_abs_z_mm
        );
        let paper_head = match t.paper_metric {
            PaperMetric::MeanAbsZ => "paper: mean |z| mm / variance mm²",
            PaperMetric::Mean3d => "paper: 3-D mean mm",
        };
        let _ = writeln!(
            html,
            "<table><tr><th>pipeline</th><th>poses</th><th>training s</th><th>mean |z| mm</th><th>variance mm²</th><th>3-D mean mm</th><th>3-D max mm</th><th>{paper_head}</th></tr>"
        );
        for r in &t.rows {
            let paper = match r.paper {
                Some(p) => match p.variance_mm2 {
                    Some(v) => format!("{:.2} / {v:.2}", p.mean_mm),
                    None => format!("{:.2}", p.mean_mm),
                },
                None => String::new(),
            };
            let _ = writeln!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{:.2}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{:.3}</td><td>{paper}</td></tr>",
                escape(&r.name),
                r.training_poses,
                r.training_s,
                r.mean_abs_z_mm,
                r.variance_mm2,
                r.mean_mm,
                r.max_mm
            );
        }
        html.push_str("</table>\n");
        for (kind, caption, draw) in plots {
            let name = format!("{stem}-{kind}.svg");
            let path = dir.join(&name);
            let svg = draw(t).map_err(|message| armcomp_core::Error::not_written(&path, message))?;
            files.push((name.clone(), svg.into_bytes()));
            let _ = writeln!(
                html,
                "<figure><img src=\"{name}\" alt=\"{caption}\"><figcaption>{caption}</figcaption></figure>"
            );
        }
    }
    for (i, c) in curves.iter().enumerate() {
        let stat = c.stat();
        let _ = writeln!(
            html,
            "<h2>{}</h2>\n<p>{} training poses, {} held out; the held-out 3-D {} error of the model fitted on the \
             poses the tool chose from the training poses, and on random subsets of them ({} seeded draws).</p>",
            escape(&c.report.title),
            c.report.train_poses,
            c.report.test_poses,
            if c.metric == "rms" { "RMS" } else { "mean" },
            c.report.points.iter().map(|p| p.random.len()).max().unwrap_or(0)
        );
        let _ = writeln!(
            html,
            "<table><tr><th>poses</th><th>chosen mm</th><th>random mean mm</th><th>random median mm</th><th>random min mm</th><th>random max mm</th></tr>"
        );
        for p in &c.report.points {
            let [mean, median, lo, hi] = p.random_summary(stat);
            let _ = writeln!(
                html,
                "<tr><td>{}</td><td>{:.3}</td><td>{mean:.3}</td><td>{median:.3}</td><td>{lo:.3}</td><td>{hi:.3}</td></tr>",
                p.size,
                stat(&p.selected)
            );
        }
        html.push_str("</table>\n");
        let name = format!("curve-{}.svg", i + 1);
        let svg =
            plots::learning_curve(c).map_err(|message| armcomp_core::Error::not_written(&dir.join(&name), message))?;
        files.push((name.clone(), svg.into_bytes()));
        let caption =
            "Held-out error against training poses: the tool's choice, and the random subsets' median with their range";
        let _ = writeln!(
            html,
            "<figure><img src=\"{name}\" alt=\"{caption}\"><figcaption>{caption}</figcaption></figure>"
        );
    }
    html.push_str("</body></html>\n");
    files.push(("index.html".into(), html.into_bytes()));
    write_folder_atomic(dir, &files)?;
    Ok(dir.join("index.html"))
}
