//! The demo report on a hand-made table: the page and its three SVGs are written, and what the
//! plots show follows from the table's values (bar lengths in proportion, value labels, histogram
//! counts worked out by hand, per-axis curves an affine image of the errors).

use armcomp_repro::demos::plots::{AFTER_COLOR, BEFORE_COLOR, MEASURED_COLOR, PAPER_COLOR};
use armcomp_repro::demos::report::write;
use armcomp_repro::demos::{PaperMetric, PaperValue, Row, Table};
use plotters::style::RGBColor;

use crate::common::Scratch;

fn row(name: &str, mean_abs_z_mm: f64, mean_mm: f64, paper: Option<f64>, errors_mm: Vec<[f64; 3]>) -> Row {
    Row {
        name: name.into(),
        paper: paper.map(|mean_mm| PaperValue {
            mean_mm,
            variance_mm2: Some(100.0),
        }),
        training_poses: 0,
        training_s: 0.0,
        mean_abs_z_mm,
        variance_mm2: 1.0,
        mean_mm,
        max_mm: 30.0,
        errors_mm,
    }
}

fn table() -> Table {
    Table {
        title: "hand-made twin: three rows".into(),
        setup: "four targets".into(),
        noise_mm: 0.5,
        noise_mean_abs_z_mm: 0.4,
        paper_metric: PaperMetric::MeanAbsZ,
        rows: vec![
            // 3-D norms 5, 10, 5, 20.
            row(
                "original",
                8.0,
                12.0,
                Some(8.5),
                vec![[3.0, 4.0, 0.0], [6.0, 8.0, 0.0], [0.0, 0.0, 5.0], [12.0, 16.0, 0.0]],
            ),
            row(
                "deflection only",
                4.0,
                6.0,
                Some(7.0),
                vec![[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0], [3.0, 0.0, 0.0]],
            ),
            // The best row (lowest 3-D mean); norms 0.5, 0.52, 1.5, 0.4.
            row(
                "calibrated",
                1.0,
                2.0,
                None,
                vec![[0.0, 0.0, 0.5], [0.0, 0.48, 0.2], [0.0, 0.0, 1.5], [0.0, 0.0, 0.4]],
            ),
        ],
    }
}

/// `name="value"` of an SVG tag.
fn attr<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let start = tag.find(&format!(" {name}=\""))? + name.len() + 3;
    Some(&tag[start..start + tag[start..].find('"')?])
}

/// The attribute lists of every `<element ...>` tag, each with a leading space.
fn tags(svg: &str, element: &str) -> Vec<String> {
    svg.split(&format!("<{element} "))
        .skip(1)
        .map(|t| format!(" {}", &t[..t.find('>').unwrap_or(t.len())]))
        .collect()
}

fn hex(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

/// A filled rectangle: x, y (top), width, height in pixels.
#[derive(Debug, Clone, Copy)]
struct Rect {
    x: f64,
    y: f64,
    w: f64,
    h: f64,
}

/// The filled rectangles of colour `c` in drawing order, legend swatches (10 × 10) left out.
fn rects(svg: &str, c: RGBColor) -> Vec<Rect> {
    tags(svg, "rect")
        .into_iter()
        .filter(|t| attr(t, "fill") == Some(hex(c).as_str()))
        .map(|t| {
            let f = |n| attr(&t, n).unwrap().parse::<f64>().unwrap();
            Rect {
                x: f("x"),
                y: f("y"),
                w: f("width"),
                h: f("height"),
            }
        })
        .filter(|r| (r.w, r.h) != (10.0, 10.0))
        .collect()
}

/// Text elements: content and anchor position, in drawing order.
fn texts(svg: &str) -> Vec<(String, f64, f64)> {
    svg.split("<text ")
        .skip(1)
        .map(|t| {
            let head = format!(" {}", &t[..t.find('>').unwrap()]);
            let body = &t[t.find('>').unwrap() + 1..];
            let f = |n| attr(&head, n).map_or(f64::NAN, |v| v.parse().unwrap_or(f64::NAN));
            (body[..body.find("</text>").unwrap()].trim().to_string(), f("x"), f("y"))
        })
        .collect()
}

fn has_text(svg: &str, s: &str) -> bool {
    texts(svg).iter().any(|t| t.0 == s)
}

#[test]
fn demo_report_plots_the_table() {
    let dir = Scratch::new("demo-report");
    let t = table();
    let page = write(&dir.0, std::slice::from_ref(&t)).unwrap();
    let html = std::fs::read_to_string(&page).unwrap();
    let read = |kind: &str| {
        let name = format!("1-hand-made-twin-{kind}.svg");
        assert!(html.contains(&format!("src=\"{name}\"")), "{html}");
        let svg = std::fs::read_to_string(dir.0.join(&name)).unwrap();
        assert!(svg.starts_with("<svg"), "{name}");
        svg
    };
    for r in &t.rows {
        assert!(html.contains(&format!("<td>{}</td>", r.name)));
    }
    // Nothing but the page and the three plots, no temporary files left behind.
    assert_eq!(std::fs::read_dir(&dir.0).unwrap().count(), 4);

    // Bars: two panels (mean |z|, then 3-D mean), one bar per row in row order, lengths in
    // proportion to the values; the paper's values (mean |z| here) in the first panel only, on
    // the same scale. Each row's name labels its own bar, and each value label sits at the end of
    // its bar.
    let bars = read("bars");
    let measured = rects(&bars, MEASURED_COLOR);
    let paper = rects(&bars, PAPER_COLOR);
    assert_eq!(measured.len(), 6, "{measured:?}");
    assert_eq!(paper.len(), 2, "{paper:?}");
    let z_unit = measured[0].w / 8.0;
    for (r, v) in measured[..3]
        .iter()
        .zip([8.0, 4.0, 1.0])
        .chain(paper.iter().zip([8.5, 7.0]))
    {
        assert!((r.w - v * z_unit).abs() <= 1.5, "{r:?} for {v}");
    }
    let unit_3d = measured[3].w / 12.0;
    for (r, v) in measured[3..].iter().zip([12.0, 6.0, 2.0]) {
        assert!((r.w - v * unit_3d).abs() <= 1.5, "{r:?} for {v}");
    }
    let labels = texts(&bars);
    let first = |s: &str| {
        labels
            .iter()
            .find(|t| t.0 == s)
            .unwrap_or_else(|| panic!("{s} in {labels:?}"))
            .clone()
    };
    for (i, r) in t.rows.iter().enumerate() {
        let bar = measured[i];
        let (_, _, y) = first(&r.name);
        let slot = (measured[1].y - measured[0].y).abs();
        assert!(
            y > bar.y - slot / 2.0 && y < bar.y + slot,
            "{} at y {y}, its bar {bar:?}",
            r.name
        );
        let (_, x, _) = first(&format!("{:.3}", r.mean_abs_z_mm));
        assert!((x - (bar.x + bar.w)).abs() <= 1.5, "label at {x}, bar {bar:?}");
    }
    for v in ["6.000", "2.000", "12.000", "paper 8.50", "paper 7.00"] {
        first(v);
    }
    assert!(has_text(&bars, "mean |z| error (mm)") && has_text(&bars, "mean 3-D error (mm)"));

    // Histograms, each on 20 bins from zero to its largest error: before, norms 5, 5, 10, 20 on
    // bins of 1 mm fill bins 4 (twice), 9 and 19; the best row, 0.4, 0.5, 0.52, 1.5 on bins of
    // 0.075 mm, fills bin 5, bin 6 twice, and bin 19. Empty bins draw nothing; one count scale.
    let hist = read("histogram");
    let before = rects(&hist, BEFORE_COLOR);
    let after = rects(&hist, AFTER_COLOR);
    assert_eq!((before.len(), after.len()), (3, 3), "{before:?} {after:?}");
    let unit = before[1].h;
    for (r, count) in before.iter().chain(&after).zip([2.0, 1.0, 1.0, 1.0, 2.0, 1.0]) {
        assert!((r.h - count * unit).abs() <= 1.5, "{before:?} {after:?}");
    }
    // Bin positions: bins 4, 9, 19 and 5, 6, 19 (pixel width from the first and last bar).
    for (bars, bins) in [(&before, [4.0, 9.0, 19.0]), (&after, [5.0, 6.0, 19.0])] {
        let px = (bars[2].x - bars[0].x) / (bins[2] - bins[0]);
        assert!(
            (bars[1].x - bars[0].x - (bins[1] - bins[0]) * px).abs() <= 1.5,
            "{bars:?}"
        );
        assert!((bars[0].w - px).abs() <= 1.0, "{bars:?}");
    }
    assert!(has_text(&hist, "3-D error at a test target (mm)"));
    assert!(has_text(&hist, "before: original") && has_text(&hist, "best: calibrated"));

    // Per axis: in each of the three panels the curve of a row is an affine image of its errors
    // along that axis (same pixel scale for both rows of a panel).
    let axes = read("axes");
    let curves: Vec<Vec<(f64, f64)>> = tags(&axes, "polyline")
        .into_iter()
        .map(|t| {
            attr(&t, "points")
                .unwrap()
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .filter(|c: &Vec<(f64, f64)>| c.len() == 4)
        .collect();
    assert_eq!(curves.len(), 6, "{curves:?}");
    for axis in 0..3 {
        let (a, b) = (&curves[2 * axis], &curves[2 * axis + 1]);
        let values: Vec<f64> = t.rows[0]
            .errors_mm
            .iter()
            .chain(&t.rows[2].errors_mm)
            .map(|e| e[axis])
            .collect();
        let ys: Vec<f64> = a.iter().chain(b).map(|p| p.1).collect();
        // Fit y = c0 + c1 v by the two extreme values, then every point must lie on it.
        let (imin, imax) = (0..8).fold((0, 0), |(lo, hi), i| {
            (
                if values[i] < values[lo] { i } else { lo },
                if values[i] > values[hi] { i } else { hi },
            )
        });
        let c1 = (ys[imax] - ys[imin]) / (values[imax] - values[imin]);
        assert!(c1 < 0.0, "larger errors plot higher");
        for i in 0..8 {
            let y = ys[imin] + c1 * (values[i] - values[imin]);
            assert!((ys[i] - y).abs() <= 1.5, "axis {axis}: {ys:?} vs {values:?}");
        }
        // Targets 1..4 evenly spaced along x, the same for both rows.
        let dx = a[1].0 - a[0].0;
        assert!(dx > 0.0);
        for (p, q) in a.iter().zip(b) {
            assert_eq!(p.0, q.0);
        }
        for w in a.windows(2) {
            assert!((w[1].0 - w[0].0 - dx).abs() <= 1.0);
        }
    }
    for axis in ["x", "y", "z"] {
        assert!(has_text(&axes, &format!("{axis} error (mm)")));
    }
}
