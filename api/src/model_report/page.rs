//! The HTML of a model report: one page, its plots inline, what matters first.

use std::fmt::Write as _;

use armcomp_report::html::escape;

use super::ModelReport;
use super::plots::{Plot, svg};

/// How many of the largest residuals the rows table lists.
const WORST_ROWS: usize = 10;

const STYLE: &str = "body{font-family:sans-serif;margin:1em 2em;max-width:1400px}\
    table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:2px 8px;text-align:right}\
    td:first-child,th:first-child{text-align:left}.warn{background:#fde8e4;border:1px solid #d6604d;padding:.4em .8em}\
    .grid{display:flex;flex-wrap:wrap;gap:8px}.grid svg{max-width:100%;height:auto}\
    .flag{color:#b2182b;font-weight:bold}h2{margin-top:1.2em;border-bottom:1px solid #ccc}";

/// The page of `r`.
pub fn html(r: &ModelReport) -> Result<String, String> {
    let mut h = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>armcomp {} — {}</title><style>{STYLE}</style>\
         </head><body>\n<h1>armcomp {}: {}</h1>\n",
        escape(&r.command),
        escape(&r.robot),
        escape(&r.command),
        escape(&r.robot)
    );
    for w in &r.warnings {
        let _ = writeln!(h, "<p class=\"warn\">{}</p>", escape(w));
    }
    figures(&mut h, r);
    // Above the fold: the ladder or the per-axis bars, and the workspace map.
    let first: Vec<&Plot> = (r.plots.iter())
        .filter(|p| ["ladder", "axes", "map_xy"].contains(&p.name.as_str()))
        .collect();
    plot_grid(&mut h, &first)?;
    held_out(&mut h, r);
    if let Some(l) = &r.ladder {
        ladder(&mut h, l);
    }
    h.push_str("<h2>Residuals</h2>\n");
    let rest: Vec<&Plot> = (r.plots.iter())
        .filter(|p| !["ladder", "axes", "map_xy"].contains(&p.name.as_str()))
        .collect();
    plot_grid(&mut h, &rest)?;
    if !r.parameters.is_empty() {
        parameters(&mut h, r);
    }
    rows(&mut h, r);
    h.push_str("<p>Every number and every plot's points are in <code>report.json</code> beside this page.</p>\n</body></html>\n");
    Ok(h)
}

/// A number as the page shows it.
fn num(v: f64) -> String {
    if v.is_finite() { format!("{v:.4}") } else { "—".into() }
}

fn figures(h: &mut String, r: &ModelReport) {
    h.push_str("<table><tr>");
    for f in &r.figures {
        let _ = write!(h, "<th>{}</th>", escape(&f.label));
    }
    h.push_str("</tr><tr>");
    for f in &r.figures {
        let value = if f.unit.is_empty() {
            format!("{}", f.value)
        } else {
            num(f.value)
        };
        let _ = write!(h, "<td data-key=\"{}\">{value}</td>", escape(&f.json_key));
    }
    h.push_str("</tr><tr>");
    for f in &r.figures {
        let _ = write!(h, "<td>{}</td>", escape(&f.unit));
    }
    h.push_str("</tr></table>\n");
}

fn plot_grid(h: &mut String, plots: &[&Plot]) -> Result<(), String> {
    h.push_str("<div class=\"grid\">\n");
    for p in plots {
        let size = match p.name.as_str() {
            "ladder" => (620, 70 + 14 * p.categories.len() as u32),
            "axes" | "map_xy" | "map_xz" | "order" | "groups" => (520, 340),
            _ => (400, 280),
        };
        let _ = writeln!(
            h,
            "<figure id=\"plot-{}\" style=\"margin:0\">{}</figure>",
            escape(&p.name),
            svg(p, size)?
        );
    }
    h.push_str("</div>\n");
    Ok(())
}

fn held_out(h: &mut String, r: &ModelReport) {
    if r.held_out.is_empty() {
        return;
    }
    h.push_str("<h2>Held out</h2>\n<table><tr><th>held out</th><th>RMS (mm)</th><th>expected (mm)</th></tr>\n");
    for x in &r.held_out {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td></tr>",
            escape(&x.what),
            x.measured_rms_mm.map_or("—".into(), num),
            x.expected_rms_mm.map_or("not recorded".into(), num)
        );
    }
    h.push_str("</table>\n");
}

fn ladder(h: &mut String, l: &super::LadderTable) {
    let _ = writeln!(
        h,
        "<h2>The ladder</h2>\n<p>Chosen: <b>{}</b>: {} (expected held-out RMS {} mm; folds by {}).</p>",
        escape(&l.chosen),
        escape(&l.reason),
        num(l.expected_rms_mm),
        escape(&l.folds_by)
    );
    h.push_str("<table><tr><th>candidate</th><th>held-out RMS (mm)</th><th>± spread (mm)</th><th></th></tr>\n");
    for (i, c) in l.candidates.iter().enumerate() {
        let mark = if c.chosen {
            "chosen"
        } else if c.within_noise {
            "within the noise"
        } else {
            ""
        };
        let sound = c.not_sound.as_deref().map_or(String::new(), |w| {
            format!(" <span class=\"flag\">not sound: {}</span>", escape(w))
        });
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td data-key=\"candidates.{i}.rms_mm\">{}</td><td>{}</td><td>{mark}{sound}</td></tr>",
            escape(&c.label),
            num(c.rms_mm),
            num(c.spread_mm)
        );
    }
    h.push_str("</table>\n");
}

fn parameters(h: &mut String, r: &ModelReport) {
    h.push_str("<h2>Parameters</h2>\n<table><tr><th>parameter</th><th>before</th><th>identified</th><th>std</th><th>unit</th><th></th></tr>\n");
    for p in &r.parameters {
        let std = match (p.fixed, p.std) {
            (true, _) => "held".to_string(),
            (false, Some(s)) => format!("{s:.4e}"),
            (false, None) => "<span class=\"flag\">undetermined</span>".to_string(),
        };
        let mut flags = Vec::new();
        if !p.plausible {
            flags.push("implausible");
        }
        if p.at_bound {
            flags.push("at a bound");
        }
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{:.6}</td><td>{:.6}</td><td>{std}</td><td>{}</td><td class=\"flag\">{}</td></tr>",
            escape(&p.name),
            p.initial,
            p.value,
            escape(&p.unit),
            flags.join(", ")
        );
    }
    h.push_str("</table>\n");
}

fn rows(h: &mut String, r: &ModelReport) {
    h.push_str("<h2>Rows</h2>\n");
    if r.outlier_rows.is_empty() {
        h.push_str("<p>No gross errors (a residual over 5 times the robust noise per axis).</p>\n");
    } else {
        let list: Vec<String> = r.outlier_rows.iter().map(usize::to_string).collect();
        let _ = writeln!(
            h,
            "<p class=\"warn\">Gross errors at data rows (0-based, as <code>--rows</code> counts them): {}</p>",
            list.join(", ")
        );
    }
    let mut order: Vec<usize> = (0..r.rows.len()).collect();
    order.sort_by(|&a, &b| r.rows[b].after_norm().total_cmp(&r.rows[a].after_norm()));
    let _ = writeln!(
        h,
        "<p>The {} largest residuals of the model:</p>\n<table><tr><th>row</th><th>point</th><th>station</th><th>kind</th>\
         <th>x (mm)</th><th>y (mm)</th><th>z (mm)</th><th>3-D (mm)</th></tr>",
        WORST_ROWS.min(r.rows.len())
    );
    for &i in order.iter().take(WORST_ROWS) {
        let x = &r.rows[i];
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            x.row,
            escape(&x.point),
            escape(&x.station),
            x.kind,
            num(x.after_mm[0]),
            num(x.after_mm[1]),
            num(x.after_mm[2]),
            num(x.after_norm())
        );
    }
    h.push_str("</table>\n");
}
