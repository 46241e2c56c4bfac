//! SVG plots of a demo table (plotters): bars of the table's rows beside the paper's values,
//! histograms of the 3-D errors before and after compensation, and the per-axis errors at every
//! test target.

use armcomp_report::histogram::bin_counts;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::report::Curve;
use super::{PaperMetric, Row, Table};

/// Colour of the measured bars (the paper's values are drawn in [`PAPER_COLOR`]).
pub const MEASURED_COLOR: RGBColor = RGBColor(31, 119, 180);
/// Colour of the paper's values.
pub const PAPER_COLOR: RGBColor = RGBColor(127, 127, 127);
/// Colour of the uncompensated errors.
pub const BEFORE_COLOR: RGBColor = RGBColor(214, 39, 40);
/// Colour of the errors of the best pipeline.
pub const AFTER_COLOR: RGBColor = MEASURED_COLOR;

/// An SVG document, or why it could not be drawn.
pub type Svg = Result<String, String>;

/// A plot of a table.
pub type Plot = fn(&Table) -> Svg;

/// A quantity of a row (mm).
type RowValue = fn(&Row) -> f64;

/// Bins of the error histograms.
pub const HISTOGRAM_BINS: usize = 20;

/// A plotting failure (plotters reports drawing errors as text).
fn draw_error(e: impl std::fmt::Display) -> String {
    format!("drawing a plot: {e}")
}

/// The row the table compensates best (lowest mean 3-D error), leaving out the first row, which
/// is always the uncompensated one.
pub fn best_row(table: &Table) -> Option<&Row> {
    table.rows.iter().skip(1).min_by(|a, b| a.mean_mm.total_cmp(&b.mean_mm))
}

/// 3-D error norms of a row (mm).
fn norms(row: &Row) -> Vec<f64> {
    row.errors_mm
        .iter()
        .map(|e| (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
        .collect()
}

/// Horizontal bars of every row: mean |z| and mean 3-D error, each with the paper's value where
/// the paper gives that quantity. Every bar carries its value as a label.
pub fn bars(table: &Table) -> Svg {
    let n = table.rows.len();
    let mut svg = String::new();
    {
        let height = 120 + 2 * 34 * n as u32;
        let root = SVGBackend::with_string(&mut svg, (1000, height)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        let panels = root.split_evenly((2, 1));
        let quantities: [(&str, PaperMetric, RowValue); 2] = [
            ("mean |z| error (mm)", PaperMetric::MeanAbsZ, |r| r.mean_abs_z_mm),
            ("mean 3-D error (mm)", PaperMetric::Mean3d, |r| r.mean_mm),
        ];
        for (panel, (label, metric, value)) in panels.iter().zip(quantities) {
            let paper = |r: &Row| r.paper.filter(|_| table.paper_metric == metric).map(|p| p.mean_mm);
            let top = table
                .rows
                .iter()
                .flat_map(|r| [Some(value(r)), paper(r)])
                .flatten()
                .fold(0.0, f64::max)
                * 1.15
                + 1e-9;
            let mut chart = ChartBuilder::on(panel)
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(340)
                .build_cartesian_2d(0.0..top, (0..n.max(1) - 1).into_segmented())
                .map_err(draw_error)?;
            chart
                .configure_mesh()
                .disable_y_mesh()
                .x_desc(label)
                .y_desc("pipeline")
                .y_labels(n)
                .y_label_formatter(&|s| match s {
                    SegmentValue::CenterOf(k) if *k < n => table.rows[n - 1 - k].name.clone(),
                    _ => String::new(),
                })
                .draw()
                .map_err(draw_error)?;
            // Row 0 at the top: row i in slot n-1-i.
            let slot = |i: usize| n - 1 - i;
            chart
                .draw_series(table.rows.iter().enumerate().map(|(i, r)| {
                    let mut bar = Rectangle::new(
                        [
                            (0.0, SegmentValue::Exact(slot(i))),
                            (value(r), SegmentValue::Exact(slot(i) + 1)),
                        ],
                        MEASURED_COLOR.filled(),
                    );
                    bar.set_margin(4, 14, 0, 0);
                    bar
                }))
                .map_err(draw_error)?
                .label("this run")
                .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], MEASURED_COLOR.filled()));
            let with_paper: Vec<(usize, f64)> = table
                .rows
                .iter()
                .enumerate()
                .filter_map(|(i, r)| paper(r).map(|p| (i, p)))
                .collect();
            if !with_paper.is_empty() {
                chart
                    .draw_series(with_paper.iter().map(|&(i, p)| {
                        let mut bar = Rectangle::new(
                            [
                                (0.0, SegmentValue::Exact(slot(i))),
                                (p, SegmentValue::Exact(slot(i) + 1)),
                            ],
                            PAPER_COLOR.filled(),
                        );
                        bar.set_margin(20, 2, 0, 0);
                        bar
                    }))
                    .map_err(draw_error)?
                    .label("paper")
                    .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], PAPER_COLOR.filled()));
            }
            let text = TextStyle::from(("sans-serif", 12).into_font());
            chart
                .draw_series(table.rows.iter().enumerate().map(|(i, r)| {
                    Text::new(
                        format!(" {:.3}", value(r)),
                        (value(r), SegmentValue::CenterOf(slot(i))),
                        text.clone().pos(Pos::new(HPos::Left, VPos::Bottom)),
                    )
                }))
                .map_err(draw_error)?;
            chart
                .draw_series(with_paper.iter().map(|&(i, p)| {
                    Text::new(
                        format!(" paper {p:.2}"),
                        (p, SegmentValue::CenterOf(slot(i))),
                        text.clone().pos(Pos::new(HPos::Left, VPos::Top)),
                    )
                }))
                .map_err(draw_error)?;
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerRight)
                .background_style(WHITE)
                .border_style(BLACK)
                .draw()
                .map_err(draw_error)?;
        }
        root.present().map_err(draw_error)?;
    }
    Ok(svg)
}

/// Histograms of the 3-D errors at the test targets before compensation (the first row) and with
/// the best pipeline, side by side, each on its own 20 bins from zero to its largest error and
/// both on one count scale.
pub fn histogram(table: &Table) -> Svg {
    let series: Vec<(String, Vec<f64>, RGBColor)> = table
        .rows
        .first()
        .map(|r| (format!("before: {}", r.name), norms(r), BEFORE_COLOR))
        .into_iter()
        .chain(best_row(table).map(|r| (format!("best: {}", r.name), norms(r), AFTER_COLOR)))
        .collect();
    let binned: Vec<(f64, Vec<usize>)> = series
        .iter()
        .map(|s| {
            let max = s.1.iter().copied().fold(0.0, f64::max) * 1.0001 + 1e-9;
            let width = max / HISTOGRAM_BINS as f64;
            (width, bin_counts(&s.1, width, HISTOGRAM_BINS))
        })
        .collect();
    let top = binned
        .iter()
        .flat_map(|b| b.1.iter().copied())
        .max()
        .unwrap_or(1)
        .max(1) as f64
        * 1.15;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1000, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        let panels = root.split_evenly((1, series.len().max(1)));
        for (panel, ((title, _, color), (width, counts))) in panels.iter().zip(series.iter().zip(&binned)) {
            let color = *color;
            let mut chart = ChartBuilder::on(panel)
                .caption(title, ("sans-serif", 16))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..width * HISTOGRAM_BINS as f64, 0.0..top)
                .map_err(draw_error)?;
            chart
                .configure_mesh()
                .x_desc("3-D error at a test target (mm)")
                .y_desc("test targets (count)")
                .y_label_formatter(&|y| format!("{y:.0}"))
                .draw()
                .map_err(draw_error)?;
            chart
                .draw_series(counts.iter().enumerate().filter(|(_, k)| **k > 0).map(|(i, &k)| {
                    let x = i as f64 * width;
                    Rectangle::new([(x, 0.0), (x + width, k as f64)], color.mix(0.6).filled())
                }))
                .map_err(draw_error)?;
        }
        root.present().map_err(draw_error)?;
    }
    Ok(svg)
}

/// The x, y and z errors at every test target (in the order the targets were drawn, along the
/// task for the industrial trajectory) before compensation and with the best pipeline.
pub fn per_axis(table: &Table) -> Svg {
    let rows: Vec<(&Row, RGBColor, &str)> = table
        .rows
        .first()
        .map(|r| (r, BEFORE_COLOR, "before"))
        .into_iter()
        .chain(best_row(table).map(|r| (r, AFTER_COLOR, "best")))
        .collect();
    let n = rows.iter().map(|r| r.0.errors_mm.len()).max().unwrap_or(0).max(1);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 780)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        for (axis, panel) in root.split_evenly((3, 1)).iter().enumerate() {
            per_axis_panel(panel, axis, &rows, n)?;
        }
        root.present().map_err(draw_error)?;
    }
    Ok(svg)
}

fn per_axis_panel(
    panel: &DrawingArea<SVGBackend<'_>, Shift>,
    axis: usize,
    rows: &[(&Row, RGBColor, &str)],
    n: usize,
) -> Result<(), String> {
    let name = ["x", "y", "z"][axis];
    let reach = rows
        .iter()
        .flat_map(|r| r.0.errors_mm.iter().map(|e| e[axis].abs()))
        .fold(0.0, f64::max)
        * 1.1
        + 1e-9;
    let mut chart = ChartBuilder::on(panel)
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5..(n as f64 + 0.5), -reach..reach)
        .map_err(draw_error)?;
    chart
        .configure_mesh()
        .x_desc("test target (number)")
        .y_desc(format!("{name} error (mm)"))
        .x_label_formatter(&|x| format!("{x:.0}"))
        .draw()
        .map_err(draw_error)?;
    for &(row, color, role) in rows {
        let points: Vec<(f64, f64)> = row
            .errors_mm
            .iter()
            .enumerate()
            .map(|(i, e)| ((i + 1) as f64, e[axis]))
            .collect();
        chart
            .draw_series(std::iter::once(PathElement::new(points.clone(), color.stroke_width(1))))
            .map_err(draw_error)?
            .label(format!("{role}: {}", row.name))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], color));
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))
            .map_err(draw_error)?;
    }
    if axis == 0 {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(draw_error)?;
    }
    Ok(())
}

/// A learning curve: held-out error against training poses for the tool's choice (a line
/// through its points), the random subsets' median (a line) with their range (bars), and the
/// reference value as a dashed horizontal line.
pub fn learning_curve(curve: &Curve) -> Svg {
    let stat = curve.stat();
    let points = &curve.report.points;
    let chosen: Vec<(f64, f64)> = points.iter().map(|p| (p.size as f64, stat(&p.selected))).collect();
    let random: Vec<(f64, [f64; 4])> = points.iter().map(|p| (p.size as f64, p.random_summary(stat))).collect();
    let top = random
        .iter()
        .map(|(_, r)| r[3])
        .chain(chosen.iter().map(|c| c.1))
        .chain(curve.reference.as_ref().map(|r| r.0))
        .fold(0.0, f64::max)
        * 1.1
        + 1e-9;
    let right = chosen.iter().map(|c| c.0).fold(1.0, f64::max) * 1.05;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_error)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(15)
            .caption(&curve.report.title, ("sans-serif", 15))
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..right, 0.0..top)
            .map_err(draw_error)?;
        chart
            .configure_mesh()
            .x_desc("training poses")
            .y_desc(format!(
                "held-out {} 3-D error (mm)",
                if curve.metric == "rms" { "RMS" } else { "mean" }
            ))
            .draw()
            .map_err(draw_error)?;
        chart
            .draw_series(
                random
                    .iter()
                    .map(|&(x, r)| PathElement::new(vec![(x, r[2]), (x, r[3])], PAPER_COLOR.stroke_width(2))),
            )
            .map_err(draw_error)?;
        chart
            .draw_series(std::iter::once(PathElement::new(
                random.iter().map(|&(x, r)| (x, r[1])).collect::<Vec<_>>(),
                PAPER_COLOR.stroke_width(2),
            )))
            .map_err(draw_error)?
            .label("random subsets: median, min–max")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], PAPER_COLOR.stroke_width(2)));
        chart
            .draw_series(
                random
                    .iter()
                    .map(|&(x, r)| Circle::new((x, r[1]), 3, PAPER_COLOR.filled())),
            )
            .map_err(draw_error)?;
        chart
            .draw_series(std::iter::once(PathElement::new(
                chosen.clone(),
                MEASURED_COLOR.stroke_width(2),
            )))
            .map_err(draw_error)?
            .label("chosen by armcomp plan")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], MEASURED_COLOR.stroke_width(2)));
        chart
            .draw_series(chosen.iter().map(|&c| Circle::new(c, 4, MEASURED_COLOR.filled())))
            .map_err(draw_error)?;
        if let Some((value, label)) = &curve.reference {
            chart
                // Dashed: 40 dashes across the plot.
                .draw_series((0..40).map(|k| {
                    let x = right * f64::from(k) / 40.0;
                    PathElement::new(vec![(x, *value), (x + 0.6 * right / 40.0, *value)], BEFORE_COLOR)
                }))
                .map_err(draw_error)?
                .label(format!("{label}: {value} mm"))
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BEFORE_COLOR));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE)
            .border_style(BLACK)
            .draw()
            .map_err(draw_error)?;
        root.present().map_err(draw_error)?;
    }
    Ok(svg)
}
