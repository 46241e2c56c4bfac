//! The plots of a model report: their data, computed from the report's rows, and their SVG,
//! drawn by plotters from those data alone, so that what a plot shows is what `report.json`
//! says it shows.

use plotters::coord::Shift;
use plotters::prelude::*;
use serde::Serialize;

use super::{ModelReport, RowResidual};

/// One plot: bars over categories, or points.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Plot {
    /// Its name in the page (`axes`, `joint_q2`, `map_xy`, ...).
    pub name: String,
    /// Its title.
    pub title: String,
    /// The horizontal axis' label, with its unit.
    pub x_label: String,
    /// The vertical axis' label, with its unit.
    pub y_label: String,
    /// For a bar chart, the bars' categories: a point's first coordinate is its category's
    /// index, its second the bar's length. Empty for a plot of points.
    pub categories: Vec<String>,
    /// Whether the bars lie along the horizontal axis (categories down the vertical one).
    pub horizontal: bool,
    /// The series drawn, each in its own colour.
    pub series: Vec<Series>,
}

/// One series of a plot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Series {
    /// Its name in the legend.
    pub name: String,
    /// Every point or bar, `[x, y]`.
    pub points: Vec<[f64; 2]>,
    /// Per point, the value its colour shows on a scale from blue (lowest) to red (highest);
    /// empty when the series has one colour.
    pub colour_values: Vec<f64>,
    /// Per bar, the half-length of its error bar; empty without.
    pub error_bars: Vec<f64>,
}

impl Series {
    fn new(name: &str, points: Vec<[f64; 2]>) -> Series {
        Series {
            name: name.into(),
            points,
            colour_values: Vec::new(),
            error_bars: Vec::new(),
        }
    }
}

/// The colours of the model as given and of the model.
const BEFORE: RGBColor = RGBColor(214, 96, 77);
const AFTER: RGBColor = RGBColor(33, 102, 172);

/// What the model's residuals are called: `fitted` when the page compares with the robot as
/// given, `model` otherwise.
fn after_name(r: &ModelReport) -> &'static str {
    if r.rows.iter().any(|x| x.before_mm.is_some()) {
        "fitted"
    } else {
        "model"
    }
}

/// The per-row series `f` gives of the residuals as given (when there are) and of the model.
fn before_after(r: &ModelReport, f: &dyn Fn(&RowResidual, f64) -> Option<[f64; 2]>) -> Vec<Series> {
    let mut series = Vec::new();
    if r.rows.iter().any(|x| x.before_mm.is_some()) {
        let points = r
            .rows
            .iter()
            .filter_map(|x| x.before_norm().and_then(|e| f(x, e)))
            .collect();
        series.push(Series::new("as given", points));
    }
    let points = r.rows.iter().filter_map(|x| f(x, x.after_norm())).collect();
    series.push(Series::new(after_name(r), points));
    series
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
}

fn points_plot(name: &str, title: &str, x_label: &str, series: Vec<Series>) -> Plot {
    Plot {
        name: name.into(),
        title: title.into(),
        x_label: x_label.into(),
        y_label: "3-D residual (mm)".into(),
        categories: Vec::new(),
        horizontal: false,
        series,
    }
}

/// Every plot of the page, from `r`'s rows and ladder.
pub fn plots(r: &ModelReport) -> Vec<Plot> {
    let mut plots = Vec::new();
    if let Some(l) = &r.ladder {
        // The choice in the model's colour, the others in the colour of what it was chosen over.
        let series: Vec<Series> = [("not chosen", false), ("chosen", true)]
            .into_iter()
            .map(|(name, chosen)| {
                let of = || (l.candidates.iter().enumerate()).filter(move |(_, c)| c.chosen == chosen);
                let mut s = Series::new(name, of().map(|(i, c)| [i as f64, c.rms_mm]).collect());
                s.error_bars = of().map(|(_, c)| c.spread_mm).collect();
                s
            })
            .collect();
        plots.push(Plot {
            name: "ladder".into(),
            title: "candidates: held-out RMS ± the folds' spread".into(),
            x_label: "held-out RMS (mm)".into(),
            y_label: String::new(),
            categories: l.candidates.iter().map(|c| c.label.clone()).collect(),
            horizontal: true,
            series,
        });
    }
    plots.push(axes(r));
    plots.extend(groups(r));
    plots.extend(maps(r));
    plots.push(points_plot(
        "order",
        "residual against row order (drift)",
        "data row",
        before_after(r, &|x, e| Some([x.row as f64, e])),
    ));
    for (j, column) in r.joint_columns.iter().enumerate() {
        let values = r.rows.iter().map(|x| x.joints[j]);
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
        // A joint the data never move says nothing.
        if hi - lo > 1e-12 {
            plots.push(points_plot(
                &format!("joint_{j}"),
                &format!("residual against {column}"),
                column,
                before_after(r, &|x, e| Some([x.joints[j], e])),
            ));
        }
    }
    for (name, label, value) in [
        (
            "temperature",
            "temperature (°C)",
            (|x: &RowResidual| x.temperature) as fn(&RowResidual) -> Option<f64>,
        ),
        ("payload", "payload (kg)", |x: &RowResidual| x.payload),
    ] {
        if r.rows.iter().any(|x| value(x).is_some()) {
            let series = before_after(r, &|x, e| value(x).map(|v| [v, e]));
            plots.push(points_plot(name, &format!("residual against {label}"), label, series));
        }
    }
    plots
}

/// The RMS of each axis of the residuals, and of their 3-D norm.
fn axes(r: &ModelReport) -> Plot {
    let of = |get: &dyn Fn(&RowResidual) -> Option<[f64; 3]>| -> Vec<[f64; 2]> {
        let mut bars: Vec<[f64; 2]> = (0..3)
            .map(|k| [k as f64, rms(r.rows.iter().filter_map(|x| get(x).map(|e| e[k])))])
            .collect();
        bars.push([3.0, rms(r.rows.iter().filter_map(|x| get(x).map(super::norm)))]);
        bars
    };
    let after = of(&|x| Some(x.after_mm));
    let mut title = "RMS residual per axis of the measurement frame, every row".to_string();
    let mut series = Vec::new();
    if r.rows.iter().any(|x| x.before_mm.is_some()) {
        let before = of(&|x| x.before_mm);
        // A robot file far from the data (a measurement frame not registered yet) would flatten
        // the model's bars: it is then named in the title, not drawn.
        if before[3][1] > 10.0 * after[3][1] {
            title = format!(
                "RMS residual per axis, every row (as given: 3-D {:.1} mm, off this scale)",
                before[3][1]
            );
        } else {
            series.push(Series::new("as given", before));
        }
    }
    series.push(Series::new(after_name(r), after));
    Plot {
        name: "axes".into(),
        title,
        x_label: "axis".into(),
        y_label: "RMS (mm)".into(),
        categories: ["x", "y", "z", "3-D"].map(String::from).to_vec(),
        horizontal: false,
        series,
    }
}

/// Which rows a bar gathers.
type RowFilter<'a> = Box<dyn Fn(&RowResidual) -> bool + 'a>;

/// The 3-D RMS per station and per kind of row, when the rows have several.
fn groups(r: &ModelReport) -> Option<Plot> {
    let mut categories: Vec<(String, RowFilter)> = Vec::new();
    let mut stations: Vec<&str> = r.rows.iter().map(|x| x.station.as_str()).collect();
    stations.dedup();
    stations.sort_unstable();
    stations.dedup();
    if stations.len() > 1 {
        for s in stations {
            categories.push((format!("station {s}"), Box::new(move |x: &RowResidual| x.station == s)));
        }
    }
    let mut kinds: Vec<&str> = r.rows.iter().map(|x| x.kind).collect();
    kinds.sort_unstable();
    kinds.dedup();
    if kinds.len() > 1 {
        for k in kinds {
            categories.push((format!("{k} rows"), Box::new(move |x: &RowResidual| x.kind == k)));
        }
    }
    if categories.is_empty() {
        return None;
    }
    let bars = |norm: &dyn Fn(&RowResidual) -> Option<f64>| -> Vec<[f64; 2]> {
        (categories.iter().enumerate())
            .map(|(i, (_, keep))| [i as f64, rms(r.rows.iter().filter(|x| keep(x)).filter_map(norm))])
            .collect()
    };
    let mut series = Vec::new();
    if r.rows.iter().any(|x| x.before_mm.is_some()) {
        series.push(Series::new("as given", bars(&RowResidual::before_norm)));
    }
    series.push(Series::new(after_name(r), bars(&|x| Some(x.after_norm()))));
    Some(Plot {
        name: "groups".into(),
        title: "3-D RMS residual per station and per kind of row".into(),
        x_label: String::new(),
        y_label: "RMS (mm)".into(),
        categories: categories.into_iter().map(|(c, _)| c).collect(),
        horizontal: false,
        series,
    })
}

/// The measured positions in two projections, coloured by the model's residual.
fn maps(r: &ModelReport) -> Vec<Plot> {
    let measured: Vec<(&RowResidual, [f64; 3])> = r.rows.iter().filter_map(|x| x.measured_mm.map(|m| (x, m))).collect();
    if measured.is_empty() {
        return Vec::new();
    }
    [("map_xy", 1, "y"), ("map_xz", 2, "z")]
        .into_iter()
        .map(|(name, k, axis)| {
            let mut s = Series::new(
                "measured position, coloured by the residual",
                measured.iter().map(|(_, m)| [m[0], m[k]]).collect(),
            );
            s.colour_values = measured.iter().map(|(x, _)| x.after_norm()).collect();
            Plot {
                name: name.into(),
                title: format!("workspace error, x–{axis} (blue: least, red: most)"),
                x_label: "x (mm), measurement frame".into(),
                y_label: format!("{axis} (mm)"),
                categories: Vec::new(),
                horizontal: false,
                series: vec![s],
            }
        })
        .collect()
}

/// The colour of `v` on the scale from `lo` (blue) to `hi` (red).
fn scale_colour(v: f64, lo: f64, hi: f64) -> HSLColor {
    let t = if hi > lo {
        ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    HSLColor((1.0 - t) * 0.62, 0.85, 0.45)
}

fn series_colour(p: &Plot, i: usize) -> RGBColor {
    if p.series.len() > 1 && i == 0 { BEFORE } else { AFTER }
}

/// The bounds of `values` with a margin of 5 % of their range (or of 1 for one value).
fn padded(values: impl Iterator<Item = f64>, from_zero: bool) -> std::ops::Range<f64> {
    let (mut lo, mut hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !lo.is_finite() {
        (lo, hi) = (0.0, 1.0);
    }
    if from_zero {
        lo = lo.min(0.0);
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 0.5 };
    (if from_zero && lo >= 0.0 { 0.0 } else { lo - pad })..hi + pad
}

/// The SVG of `p`, `size` pixels wide and high.
pub fn svg(p: &Plot, size: (u32, u32)) -> Result<String, String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        if p.categories.is_empty() {
            draw_points(&root, p)
        } else {
            draw_bars(&root, p)
        }
        .map_err(|e| format!("plot {}: {e}", p.name))?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(out)
}

type Drawn = Result<(), DrawingAreaErrorKind<std::io::Error>>;

fn draw_points(root: &DrawingArea<SVGBackend, Shift>, p: &Plot) -> Drawn {
    let all = || p.series.iter().flat_map(|s| s.points.iter());
    let x = padded(all().map(|q| q[0]), false);
    let y = padded(all().map(|q| q[1]), p.name != "map_xy" && p.name != "map_xz");
    let mut chart = ChartBuilder::on(root)
        .caption(&p.title, ("sans-serif", 15))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_desc(&p.x_label)
        .y_desc(&p.y_label)
        .light_line_style(WHITE)
        .draw()?;
    for (i, s) in p.series.iter().enumerate() {
        let colour = series_colour(p, i);
        let (lo, hi) = (s.colour_values.iter()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
        let drawn = chart.draw_series(s.points.iter().enumerate().map(|(k, q)| {
            let style = match s.colour_values.get(k) {
                Some(v) => scale_colour(*v, lo, hi).filled(),
                None => colour.mix(0.7).filled(),
            };
            Circle::new((q[0], q[1]), 3, style)
        }))?;
        if s.colour_values.is_empty() {
            drawn
                .label(&s.name)
                .legend(move |(x, y)| Circle::new((x + 5, y), 4, colour.filled()));
        }
    }
    if p.series.iter().any(|s| s.colour_values.is_empty()) {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

fn draw_bars(root: &DrawingArea<SVGBackend, Shift>, p: &Plot) -> Drawn {
    let n = p.categories.len() as f64;
    let value = padded(
        p.series.iter().flat_map(|s| {
            s.points
                .iter()
                .enumerate()
                .map(|(k, q)| q[1] + s.error_bars.get(k).unwrap_or(&0.0))
        }),
        true,
    );
    let category = -0.5..n - 0.5;
    let label = |v: &f64| -> String {
        let k = v.round();
        if (v - k).abs() < 1e-6 && k >= 0.0 {
            p.categories.get(k as usize).cloned().unwrap_or_default()
        } else {
            String::new()
        }
    };
    // Vertical bars of several series stand side by side; horizontal ones, one series per
    // category, take its whole width.
    let width = if p.horizontal { 0.8 } else { 0.8 / p.series.len() as f64 };
    // A bar's span across its category and along its value.
    let bar = |i: usize, q: &[f64; 2]| {
        let c0 = q[0] - 0.4 + if p.horizontal { 0.0 } else { width * i as f64 };
        (c0, c0 + width, q[1])
    };
    // One chart for both orientations: `at` puts a (category, value) point where the
    // orientation draws it.
    let at = |c: f64, v: f64| if p.horizontal { (v, c) } else { (c, v) };
    let (x_range, y_range) = if p.horizontal {
        (value, category)
    } else {
        (category, value)
    };
    let longest = p.categories.iter().map(|c| c.chars().count()).max().unwrap_or(0);
    let mut chart = ChartBuilder::on(root)
        .caption(&p.title, ("sans-serif", 15))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(if p.horizontal {
            (longest as u32 * 6 + 16).min(420)
        } else {
            56
        })
        .build_cartesian_2d(x_range, y_range)?;
    let count = p.categories.len().max(1);
    let mut mesh = chart.configure_mesh();
    mesh.light_line_style(WHITE);
    if p.horizontal {
        mesh.x_desc(&p.x_label).y_labels(count).y_label_formatter(&label);
    } else {
        mesh.y_desc(&p.y_label).x_labels(count).x_label_formatter(&label);
    }
    mesh.draw()?;
    for (i, s) in p.series.iter().enumerate() {
        let colour = series_colour(p, i);
        chart
            .draw_series(s.points.iter().map(|q| {
                let (c0, c1, v) = bar(i, q);
                Rectangle::new([at(c0, 0.0), at(c1, v)], colour.mix(0.6).filled())
            }))?
            .label(&s.name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 4), (x + 10, y + 4)], colour.mix(0.6).filled()));
        chart.draw_series(s.points.iter().zip(&s.error_bars).map(|(q, e)| {
            let (c0, c1, _) = bar(i, q);
            let c = (c0 + c1) / 2.0;
            PathElement::new(vec![at(c, q[1] - e), at(c, q[1] + e)], BLACK)
        }))?;
    }
    // A legend of one series would only hide bars. Upper right: the ladder's best rungs, the
    // shortest bars, come first.
    if p.series.len() > 1 {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}
