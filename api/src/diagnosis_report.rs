//! The diagnosis report folder: an HTML page with the steps table and rankings and, drawn
//! inline, the plots of the held-out RMS per step and of the held-out error histograms; the
//! JSON report, and the plots again as SVG files.

use std::fmt::Write as _;
use std::path::Path;

use armcomp_core::Result;
use armcomp_core::algorithms::evaluate::ErrorStats;
use armcomp_core::analysis::diagnose::DiagnosisReport;
use armcomp_core::support::io::{check_report_folder, write_folder_atomic};
use armcomp_report::histogram::bin_counts;
use armcomp_report::html::{escape, page_start};
use plotters::prelude::*;

/// Whether a file belongs in a diagnosis report folder.
fn is_report_file(name: &str) -> bool {
    matches!(name, "index.html" | "report.json") || name.ends_with(".svg")
}

/// Checks, before the diagnosis runs, that `dir` may receive the report (see
/// [`check_report_folder`]): absent, or an earlier report holding none of `inputs`.
pub fn check(dir: &Path, inputs: &[std::path::PathBuf]) -> Result<()> {
    check_report_folder(dir, &is_report_file, inputs)
}

/// Writes the folder `dir` with `index.html`, `report.json`, `heldout_rms.svg` and
/// `residuals.svg`, whole: into a temporary folder, then moved into place.
/// A plot that could not be drawn is an error writing its file, as in the demo's report.
pub fn write(dir: &Path, report: &DiagnosisReport) -> Result<()> {
    let plot = |name: &str, svg: Svg| svg.map_err(|e| armcomp_core::Error::not_written(&dir.join(name), e.to_string()));
    let (rms, residuals) = (
        plot("heldout_rms.svg", rms_plot(report))?,
        plot("residuals.svg", histogram(report))?,
    );
    let page = html(report, &[&rms, &residuals]);
    let files = [
        ("heldout_rms.svg", rms),
        ("residuals.svg", residuals),
        // Plain numbers, strings and lists: serialising cannot fail.
        (
            "report.json",
            serde_json::to_string_pretty(report).expect("the report serialises"),
        ),
        ("index.html", page),
    ];
    let files: Vec<(String, Vec<u8>)> = files
        .into_iter()
        .map(|(n, t)| (n.to_string(), t.into_bytes()))
        .collect();
    write_folder_atomic(dir, &files)
}

/// An SVG document, or plotters' drawing error.
type Svg = std::result::Result<String, DrawingAreaErrorKind<std::io::Error>>;

/// Held-out RMS after each step (step 0 is the model as given).
fn rms_plot(r: &DiagnosisReport) -> Svg {
    let rms: Vec<f64> = std::iter::once(r.initial.rms_mm)
        .chain(r.steps.iter().map(|s| s.heldout_after.rms_mm))
        .collect();
    let top = rms.iter().copied().fold(0.0, f64::max) * 1.1 + 1e-9;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 400)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("held-out RMS per step", ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.5..(rms.len() as f64 - 0.5), 0.0..top)?;
        chart
            .configure_mesh()
            .x_desc("step")
            .y_desc("held-out RMS (mm)")
            .x_labels(rms.len().max(2))
            .x_label_formatter(&|x| format!("{x:.0}"))
            .draw()?;
        chart.draw_series(
            rms.iter()
                .enumerate()
                .map(|(i, v)| Rectangle::new([(i as f64 - 0.3, 0.0), (i as f64 + 0.3, *v)], BLUE.mix(0.6).filled())),
        )?;
    }
    Ok(svg)
}

/// Histograms of the held-out error norms of the model as given and of the final model.
fn histogram(r: &DiagnosisReport) -> Svg {
    let first = r.heldout_norms_mm.first().cloned().unwrap_or_default();
    let last = r.heldout_norms_mm.last().cloned().unwrap_or_default();
    let max = first.iter().chain(&last).copied().fold(0.0, f64::max) + 1e-9;
    let bins = 20;
    let width = max / bins as f64;
    let (c0, c1) = (bin_counts(&first, width, bins), bin_counts(&last, width, bins));
    let top = c0.iter().chain(&c1).copied().max().unwrap_or(1) as f64 * 1.1;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (640, 400)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("held-out error norms", ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..max, 0.0..top)?;
        chart.configure_mesh().x_desc("3-D error (mm)").y_desc("poses").draw()?;
        for (counts, color, label) in [(&c0, RED, "model as given"), (&c1, BLUE, "after diagnosis")] {
            chart
                .draw_series(counts.iter().enumerate().map(|(i, &n)| {
                    let x = i as f64 * width;
                    Rectangle::new([(x, 0.0), (x + width, n as f64)], color.mix(0.4).filled())
                }))?
                .label(label)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], color.mix(0.4).filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE)
            .border_style(BLACK)
            .draw()?;
    }
    Ok(svg)
}

fn cells(s: &ErrorStats) -> String {
    format!(
        "<td>{:.4}</td><td>{:.4}</td><td>{:.4}</td>",
        s.mean_mm, s.rms_mm, s.max_mm
    )
}

/// What the report's rows are, for its header: `measured positions`, or for contacts the
/// error they are scored by (`rows scored by plane height`).
pub fn rows_scored_by(r: &DiagnosisReport) -> String {
    if r.scored_by == "position" {
        "measured positions".into()
    } else {
        format!("rows scored by {}", r.scored_by)
    }
}

/// The page, with `plots` (SVG documents) drawn inline: it needs no other file.
fn html(r: &DiagnosisReport, plots: &[&str]) -> String {
    let mut h = page_start("armcomp diagnosis", "Diagnosis");
    let _ = writeln!(
        h,
        "<p>{} {}, held-out scores in mm (folds: {}, grouped by {}).</p>",
        r.n_samples,
        rows_scored_by(r),
        r.folds,
        r.grouped_by
    );
    h.push_str("<table><tr><th>step</th><th>effect</th><th>mean</th><th>RMS</th><th>max</th><th>removed</th></tr>\n");
    let _ = writeln!(
        h,
        "<tr><td>0</td><td>model as given</td>{}<td></td></tr>",
        cells(&r.initial)
    );
    for (i, s) in r.steps.iter().enumerate() {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td>{}<td>{:.1}%</td></tr>",
            i + 1,
            escape(&s.label),
            cells(&s.heldout_after),
            100.0 * s.share_removed
        );
    }
    h.push_str("</table>\n");
    if !r.per_kind.is_empty() {
        h.push_str(
            "<p>Each kind of row on its own:</p>\n<table><tr><th>rows</th><th>n</th><th>held-out RMS as given</th>\
             <th>at the end</th></tr>\n",
        );
        for k in &r.per_kind {
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{:.4} mm</td><td>{:.4} mm</td></tr>",
                escape(&k.kind),
                k.n,
                k.before_rms_mm,
                k.after_rms_mm
            );
        }
        h.push_str("</table>\n");
    }
    h.push_str("<p>");
    for svg in plots {
        h.push_str(svg);
    }
    h.push_str("</p>\n");
    for (i, s) in r.steps.iter().enumerate() {
        let _ = writeln!(
            h,
            "<h2>Step {}: {}</h2>\n<p>{}</p>",
            i + 1,
            escape(&s.label),
            escape(&s.summary)
        );
        h.push_str("<table><tr><th>candidate</th><th>params (determined / added)</th><th>held-out RMS (mm)</th><th>removed</th><th>verdict</th><th>data cannot tell it from the first</th></tr>\n");
        for c in &s.ranking {
            let rms = c.heldout.map_or_else(
                || if c.refitted { "failed" } else { "not refitted" }.to_string(),
                |x| format!("{:.4}", x.rms_mm),
            );
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{} / {}</td><td>{rms}</td><td>{:.1}%</td><td>{}</td><td>{}</td></tr>",
                escape(&c.label),
                c.identified_params,
                c.n_params,
                100.0 * c.share_removed,
                escape(&c.verdict),
                if c.indistinguishable_from_best { "yes" } else { "" }
            );
        }
        h.push_str("</table>\n");
    }
    if let Some(l) = &r.learnable_residual {
        let _ = writeln!(
            h,
            "<h2>Learnable residual</h2><p>{}: held-out RMS {:.4} → {:.4} mm ({:.0}% unexplained but learnable).</p>",
            escape(&l.predictor),
            l.heldout_before.rms_mm,
            l.heldout_after.rms_mm,
            100.0 * l.share_learnable
        );
    }
    h.push_str("</body></html>\n");
    h
}
