//! The report pages of `calibrate`, `evaluate` and `fit` (`--report DIR`), run as a user runs
//! them: every figure on the page is the one `--json` prints, every row's residual is the one
//! `evaluate --residuals` writes, every plot's points follow from those rows and the data file,
//! and each drawn plot holds as many marks as it has points. A headless browser opens the page
//! where one is installed (see `page_opens_in_a_browser_without_errors_and_its_plots_are_drawn`).

use std::path::Path;

use serde_json::Value;

use crate::cli::armcomp;
use crate::common::Scratch;

/// `v` at the dot-separated `key` (`after.rms_mm`, `candidates.3.rms_mm`).
fn at<'a>(v: &'a Value, key: &str) -> &'a Value {
    key.split('.').fold(v, |v, k| match k.parse::<usize>() {
        Ok(i) => &v[i],
        Err(_) => &v[k],
    })
}

/// Every `data-key="K">V<` cell of the page: (K, V).
fn keyed_cells(html: &str) -> Vec<(String, String)> {
    html.split("data-key=\"")
        .skip(1)
        .map(|t| {
            let key = &t[..t.find('"').unwrap()];
            let value = &t[t.find('>').unwrap() + 1..t.find('<').unwrap()];
            (key.to_string(), value.to_string())
        })
        .collect()
}

/// Checks that every keyed figure of the page is `json`'s value at its key, as the page rounds it.
fn assert_figures_are_the_json(html: &str, json: &Value, at_least: usize) {
    let cells = keyed_cells(html);
    assert!(cells.len() >= at_least, "{} keyed cells", cells.len());
    for (key, shown) in cells {
        let v = at(json, &key)
            .as_f64()
            .unwrap_or_else(|| panic!("--json has no number at {key}"));
        let expected = if shown.contains('.') {
            format!("{v:.4}")
        } else {
            format!("{v}")
        };
        assert_eq!(shown, expected, "{key}");
    }
}

/// The columns of a CSV by header name.
fn csv_columns(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<String> = lines.next().unwrap().split(',').map(|h| h.trim().to_string()).collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|c| c.trim().parse().unwrap_or(f64::NAN)).collect())
        .collect();
    (header, rows)
}

fn column(header: &[String], rows: &[Vec<f64>], name: &str) -> Vec<f64> {
    let k = header
        .iter()
        .position(|h| h.starts_with(name))
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"));
    rows.iter().map(|r| r[k]).collect()
}

fn plot<'a>(report: &'a Value, name: &str) -> &'a Value {
    report["plots"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == name)
        .unwrap_or_else(|| panic!("no plot {name}"))
}

fn points(series: &Value) -> Vec<[f64; 2]> {
    series["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()])
        .collect()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + b.abs())
}

/// The inline SVG of plot `name` in the page.
fn svg_of<'a>(html: &'a str, name: &str) -> &'a str {
    let start = html
        .find(&format!("<figure id=\"plot-{name}\""))
        .unwrap_or_else(|| panic!("no figure {name}"));
    let end = start + html[start..].find("</figure>").unwrap();
    &html[start..end]
}

fn simulate(dir: &Path, name: &str, n: &str, seed: &str) -> String {
    let out = dir.join(name).display().to_string();
    let (code, _, err) = armcomp(&[
        "simulate",
        "--robot",
        "robots/industrial-6dof-truth.toml",
        "--n",
        n,
        "--noise-mm",
        "0.05",
        "--seed",
        seed,
        "--out",
        &out,
    ]);
    assert_eq!(code, 0, "{err}");
    out
}

#[test]
fn calibrate_and_evaluate_pages_show_the_json_figures_and_the_rows_residuals() {
    let s = Scratch::new("model-report");
    let train = simulate(&s.0, "train.csv", "40", "1");
    let test = simulate(&s.0, "test.csv", "25", "2");
    let model = s.0.join("model.toml").display().to_string();
    let dir = s.0.join("calibration");
    let (code, out, err) = armcomp(&[
        "calibrate",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &train,
        "--out",
        &model,
        "--report",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(code == 0 || code == 2, "{err}");
    let json: Value = serde_json::from_str(&out).unwrap();
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let report: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    assert_figures_are_the_json(&html, &json, 4);
    // Nothing is fetched: no script, no link or source elsewhere (the SVGs' namespaces are names).
    for fetch in ["<script", "src=", "href=", "url(", "@import"] {
        assert!(!html.contains(fetch), "the page holds `{fetch}`");
    }

    // The rows' residuals are the written model's, as `evaluate --residuals` computes them, and
    // the robot file's before the fit, whose RMS calibrate reports.
    let residuals = s.0.join("residuals.csv");
    let (code, _, err) = armcomp(&[
        "evaluate",
        "--model",
        &model,
        "--data",
        &train,
        "--residuals",
        residuals.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let (header, csv) = csv_columns(&residuals);
    let to_mm = if header.iter().any(|h| h.ends_with("[m]")) {
        1e3
    } else {
        1.0
    };
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), csv.len());
    for (axis, name) in ["x_err", "y_err", "z_err"].iter().enumerate() {
        for (r, e) in rows.iter().zip(column(&header, &csv, name)) {
            assert!(
                close(r["after_mm"][axis].as_f64().unwrap(), e * to_mm, 1e-9),
                "{name}: {r} against {e}"
            );
        }
    }
    let rms = |key: &str| {
        let sum: f64 = rows
            .iter()
            .map(|r| (0..3).map(|k| r[key][k].as_f64().unwrap().powi(2)).sum::<f64>())
            .sum();
        (sum / rows.len() as f64).sqrt()
    };
    assert!(close(rms("after_mm"), json["after"]["rms_mm"].as_f64().unwrap(), 1e-6));
    assert!(close(
        rms("before_mm"),
        json["before"]["rms_mm"].as_f64().unwrap(),
        1e-6
    ));

    // Each joint plot is the data file's joint column against the rows' 3-D residuals; the
    // per-axis bars are the residuals' RMS per axis; each point is one circle of the SVG.
    let (data_header, data) = csv_columns(Path::new(&train));
    let joints = report["joint_columns"].as_array().unwrap();
    for (j, name) in joints.iter().enumerate() {
        let joint = name.as_str().unwrap().split(' ').next().unwrap();
        let q = column(&data_header, &data, &format!("{joint}["));
        let p = plot(&report, &format!("joint_{j}"));
        let after = points(&p["series"][1]);
        for ((pt, q), r) in after.iter().zip(&q).zip(rows) {
            let norm = (0..3)
                .map(|k| r["after_mm"][k].as_f64().unwrap().powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(
                close(pt[0], *q, 1e-9) && close(pt[1], norm, 1e-9),
                "{pt:?} against {q}, {norm}"
            );
        }
        let circles = svg_of(&html, &format!("joint_{j}")).matches("<circle").count();
        // Both series' points, and the legend's two marks.
        assert_eq!(circles, 2 * q.len() + 2, "joint {j}");
    }
    // The model's bars are the last series (the robot as given, when drawn, the first).
    let bars = points(plot(&report, "axes")["series"].as_array().unwrap().last().unwrap());
    for (k, name) in ["x_err", "y_err", "z_err"].iter().enumerate() {
        let e = column(&header, &csv, name);
        let expected = (e.iter().map(|v| (v * to_mm).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
        assert!(close(bars[k][1], expected, 1e-9), "{name}");
    }
    assert!(close(bars[3][1], json["after"]["rms_mm"].as_f64().unwrap(), 1e-6));
    let map = plot(&report, "map_xy");
    let measured = (column(&data_header, &data, "x["), column(&data_header, &data, "y["));
    let data_to_mm = if data_header.iter().any(|h| h == "x[m]") {
        1e3
    } else {
        1.0
    };
    for (pt, (x, y)) in points(&map["series"][0]).iter().zip(measured.0.iter().zip(&measured.1)) {
        assert!(close(pt[0], x * data_to_mm, 1e-9) && close(pt[1], y * data_to_mm, 1e-9));
    }

    // `evaluate`'s page on held-out rows: its figures are its `--json`'s.
    let dir = s.0.join("held-out");
    let (code, out, err) = armcomp(&[
        "evaluate",
        "--model",
        &model,
        "--data",
        &test,
        "--report",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let json: Value = serde_json::from_str(&out).unwrap();
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert_figures_are_the_json(&html, &json, 4);
    // The report folder is refused as the place of another output it would replace.
    let inside = dir.join("r.csv");
    let (code, _, err) = armcomp(&[
        "evaluate",
        "--model",
        &model,
        "--data",
        &test,
        "--report",
        dir.to_str().unwrap(),
        "--residuals",
        inside.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lies in the report folder"), "{err}");
}

#[test]
fn fit_page_shows_every_candidate_and_evaluate_sets_the_expectation_beside_the_held_out_figure() {
    let s = Scratch::new("fit-report");
    let train = simulate(&s.0, "train.csv", "30", "3");
    let test = simulate(&s.0, "test.csv", "20", "4");
    let model = s.0.join("fit.toml").display().to_string();
    let dir = s.0.join("fit");
    let (code, out, err) = armcomp(&[
        "fit",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &train,
        "--out",
        &model,
        "--repeats",
        "1",
        "--folds",
        "3",
        "--predictor",
        "none",
        "--report",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(code == 0 || code == 2, "{err}");
    let json: Value = serde_json::from_str(&out).unwrap();
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let report: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let candidates = json["candidates"].as_array().unwrap().len();
    // Every candidate's score, and the headline figures.
    assert_figures_are_the_json(&html, &json, candidates + 4);
    // Each candidate is one bar, in the chosen series or the other, at its score.
    let ladder = plot(&report, "ladder");
    let mut bars: Vec<[f64; 2]> = points(&ladder["series"][0])
        .into_iter()
        .chain(points(&ladder["series"][1]))
        .collect();
    bars.sort_by(|a, b| a[0].total_cmp(&b[0]));
    assert_eq!(bars.len(), candidates);
    for (i, p) in bars.iter().enumerate() {
        assert_eq!(p, &[i as f64, json["candidates"][i]["rms_mm"].as_f64().unwrap()]);
    }
    let chosen: Vec<usize> = points(&ladder["series"][1]).iter().map(|p| p[0] as usize).collect();
    assert!(!chosen.is_empty(), "the choice is drawn");
    for i in chosen {
        assert_eq!(report["ladder"]["candidates"][i]["chosen"], true);
    }

    let dir = s.0.join("held-out");
    let (code, _, err) = armcomp(&[
        "evaluate",
        "--model",
        &model,
        "--data",
        &test,
        "--report",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let report: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["held_out"][0]["expected_rms_mm"], json["expected_rms_mm"]);
}

/// The browser the page is opened in: `ARMCOMP_BROWSER`, else Debian's `chromium` where it is
/// installed (`.ci/run` installs it where it can and then sets `ARMCOMP_REQUIRE_BROWSER`).
fn browser() -> Option<String> {
    if let Ok(b) = std::env::var("ARMCOMP_BROWSER") {
        return Some(b);
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
        .into_iter()
        .find(|p| Path::new(p).exists())
        .map(String::from)
}

#[test]
fn page_opens_in_a_browser_without_errors_and_its_plots_are_drawn() {
    let Some(browser) = browser() else {
        assert!(
            std::env::var_os("ARMCOMP_REQUIRE_BROWSER").is_none(),
            "ARMCOMP_REQUIRE_BROWSER is set but no chromium was found"
        );
        eprintln!("skipped: no chromium (install Debian's `chromium`, or set ARMCOMP_BROWSER)");
        return;
    };
    let s = Scratch::new("report-browser");
    let train = simulate(&s.0, "train.csv", "40", "5");
    let model = s.0.join("model.toml").display().to_string();
    let dir = s.0.join("report");
    let (code, _, err) = armcomp(&[
        "calibrate",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &train,
        "--out",
        &model,
        "--report",
        dir.to_str().unwrap(),
    ]);
    assert!(code == 0 || code == 2, "{err}");
    let page = format!("file://{}", dir.join("index.html").display());
    let shot = s.0.join("shot.png");
    let out = std::process::Command::new(&browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--enable-logging=stderr",
            "--v=0",
            "--hide-scrollbars",
            "--window-size=1280,900",
            &format!("--screenshot={}", shot.display()),
            &page,
        ])
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{log}");
    assert!(!log.contains("CONSOLE"), "console messages: {log}");
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    // Coloured pixels (the plots' bars and points; text and axes are grey): a blank or
    // unstyled page has none.
    let coloured = buf[..info.buffer_size()]
        .chunks(channels)
        .filter(|p| p.len() >= 3 && p[..3].iter().max().unwrap() - p[..3].iter().min().unwrap() > 60)
        .count();
    assert!(coloured > 2000, "{coloured} coloured pixels above the fold");
}
