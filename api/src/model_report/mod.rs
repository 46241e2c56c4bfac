//! The report folder of `fit`, `calibrate` and `evaluate` (`--report DIR`): one HTML page that
//! needs no network, with its plots drawn inline, and `report.json`, every number and every
//! plot's points the page shows.
//!
//! The page is built from a [`ModelReport`], which holds the figures the command's `--json`
//! prints (each with its key there), the ladder, the parameters, every row's residual before
//! and after, and the data of every plot ([`plots::Plot`]), computed from those rows.

mod page;
pub mod plots;

use std::path::{Path, PathBuf};

use armcomp_core::Robot;
use armcomp_core::analysis::ladder::Ladder;
use armcomp_core::calibrate::{CalibrationReport, ParamResult};
use armcomp_core::data::measurement::{Sample, SampleKind};
use armcomp_core::support::io::{check_report_folder, write_folder_atomic};
use serde::Serialize;

use crate::ops::calibrate::CalibrationRun;
use crate::ops::evaluate::EvaluationReport;
use plots::Plot;

/// What one report page shows.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ModelReport {
    /// The command that wrote it (`fit`, `calibrate`, `evaluate`).
    pub command: String,
    /// The robot's name.
    pub robot: String,
    /// The headline figures, each as the command's `--json` holds it.
    pub figures: Vec<Figure>,
    /// What to read before the figures: a fit that did not converge, a choice that is not
    /// sound, values that describe no robot.
    pub warnings: Vec<String>,
    /// Held-out figures beside what was expected of them.
    pub held_out: Vec<HeldOut>,
    /// The candidates `fit` scored, when the page is `fit`'s.
    pub ladder: Option<LadderTable>,
    /// The identified parameters (empty for `evaluate`).
    pub parameters: Vec<ParameterRow>,
    /// Every sample's residual, in data order.
    pub rows: Vec<RowResidual>,
    /// The data rows (0-based, as `--rows` counts them) of the gross errors, largest first.
    pub outlier_rows: Vec<usize>,
    /// The joint names of [`RowResidual::joints`], each with its unit.
    pub joint_columns: Vec<String>,
    /// Every plot the page draws, with its points.
    pub plots: Vec<Plot>,
}

/// A headline figure: its label, its value and where `--json` holds it.
#[derive(Debug, Clone, Serialize)]
pub struct Figure {
    /// What it is, in words.
    pub label: String,
    /// Its path in the command's `--json` output, dot-separated (`after.rms_mm`).
    pub json_key: String,
    /// Its value, in `unit`.
    pub value: f64,
    /// Its unit (`mm`, `deg`, empty for a count).
    pub unit: String,
}

/// A held-out figure and the figure expected of it (mm).
#[derive(Debug, Clone, Serialize)]
pub struct HeldOut {
    /// What was held out.
    pub what: String,
    /// The held-out RMS, when these rows are held out.
    pub measured_rms_mm: Option<f64>,
    /// What cross-validation expected, when it was asked.
    pub expected_rms_mm: Option<f64>,
}

/// `fit`'s candidates, as its ladder prints them.
#[derive(Debug, Clone, Serialize)]
pub struct LadderTable {
    /// Every candidate, in the ladder's order.
    pub candidates: Vec<LadderRow>,
    /// The choice, in words.
    pub chosen: String,
    /// Why.
    pub reason: String,
    /// The held-out RMS expected of the choice (mm).
    pub expected_rms_mm: f64,
    /// What the folds held out together.
    pub folds_by: String,
}

/// One candidate of the ladder.
#[derive(Debug, Clone, Serialize)]
pub struct LadderRow {
    /// Its name.
    pub label: String,
    /// Pooled held-out RMS (mm).
    pub rms_mm: f64,
    /// Standard deviation of its folds' RMS (mm).
    pub spread_mm: f64,
    /// Whether it is the choice or a member of the chosen stack.
    pub chosen: bool,
    /// Whether it scored within the noise of the best.
    pub within_noise: bool,
    /// Why it is not sound, if so.
    pub not_sound: Option<String>,
}

/// One identified parameter, in the unit people read it in.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterRow {
    /// Its dotted name.
    pub name: String,
    /// The unit of the three values (`mm`, `deg`, or SI).
    pub unit: String,
    /// Before the fit.
    pub initial: f64,
    /// Identified.
    pub value: f64,
    /// Its standard deviation; `None` when nothing in the data or the priors fixes it.
    pub std: Option<f64>,
    /// Whether it was held at its start because the data cannot determine it.
    pub fixed: bool,
    /// Whether the fit left it on a physical bound.
    pub at_bound: bool,
    /// Whether it lies in its model's plausible range.
    pub plausible: bool,
}

/// One sample's residual, measured minus modelled, in the measurement frame of its station.
#[derive(Debug, Clone, Serialize)]
pub struct RowResidual {
    /// Its data row (0-based, as `--rows` counts them).
    pub row: usize,
    /// The measured point.
    pub point: String,
    /// Its station's name (empty for data from one).
    pub station: String,
    /// `position`, `plane` or `fixed point`.
    pub kind: &'static str,
    /// The joint values, in the robot file's units ([`ModelReport::joint_columns`]).
    pub joints: Vec<f64>,
    /// The measured position (mm); `None` for a contact, which measures none.
    pub measured_mm: Option<[f64; 3]>,
    /// The residual of the robot as given (mm), when the command fitted a model.
    pub before_mm: Option<[f64; 3]>,
    /// The residual of the model (mm).
    pub after_mm: [f64; 3],
    /// The ambient temperature (°C), when the data give it.
    pub temperature: Option<f64>,
    /// The payload (kg), when the data give it.
    pub payload: Option<f64>,
}

impl RowResidual {
    /// The 3-D norm of the model's residual (mm).
    pub fn after_norm(&self) -> f64 {
        norm(self.after_mm)
    }
    /// The 3-D norm of the residual as given (mm).
    pub fn before_norm(&self) -> Option<f64> {
        self.before_mm.map(norm)
    }
}

fn norm(v: [f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Whether a file belongs in a model report folder.
fn is_report_file(name: &str) -> bool {
    matches!(name, "index.html" | "report.json")
}

/// Checks, before any work, that `dir` may receive the report (see [`check_report_folder`]):
/// absent, or an earlier report holding none of `inputs`.
pub fn check(dir: &Path, inputs: &[PathBuf]) -> armcomp_core::Result<()> {
    check_report_folder(dir, &is_report_file, inputs)
}

/// Writes the folder `dir` with `index.html` and `report.json`, whole: into a temporary
/// folder, then moved into place.
pub fn write(dir: &Path, report: &ModelReport) -> armcomp_core::Result<()> {
    let html = page::html(report).map_err(|e| armcomp_core::Error::not_written(&dir.join("index.html"), e))?;
    // Plain numbers, strings and lists: serialising cannot fail.
    let json = serde_json::to_string_pretty(report).expect("the report serialises");
    write_folder_atomic(
        dir,
        &[
            ("index.html".to_string(), html.into_bytes()),
            ("report.json".to_string(), json.into_bytes()),
        ],
    )
}

/// The page of `evaluate`: `model` scored on `samples` (data rows `rows`), `report` its result.
pub fn for_evaluate(
    model: &Robot,
    samples: &[Sample],
    rows: &[usize],
    report: &EvaluationReport,
) -> armcomp_core::Result<ModelReport> {
    let s = &report.stats;
    let mut figures = vec![
        figure("rows scored", "n", s.n as f64, ""),
        figure("RMS", "rms_mm", s.rms_mm, "mm"),
        figure("mean", "mean_mm", s.mean_mm, "mm"),
        figure("max", "max_mm", s.max_mm, "mm"),
    ];
    if let Some(o) = &report.orientation {
        figures.push(figure("orientation RMS", "orientation.rms_deg", o.rms_deg, "deg"));
    }
    let expected = model.built_from().fitted.as_ref().and_then(|f| f.expected_rms_mm);
    let held_out = vec![HeldOut {
        what: "these rows, by the model".into(),
        measured_rms_mm: Some(s.rms_mm),
        expected_rms_mm: expected,
    }];
    let report = ModelReport {
        command: "evaluate".into(),
        figures,
        held_out,
        rows: residual_rows(model, samples, rows, None, &report.errors),
        ..ModelReport::default()
    };
    Ok(finish(model, report))
}

/// The page of `calibrate`: `given` (with the data's stations) calibrated on `samples` as `run`.
pub fn for_calibrate(
    given: &Robot,
    samples: &[Sample],
    rows: &[usize],
    run: &CalibrationRun,
) -> armcomp_core::Result<ModelReport> {
    let r = &run.calibration.report;
    let mut figures = calibration_figures(r, "");
    if let Some(e) = &run.evidence {
        figures.push(figure("noise per axis", "evidence.noise_mm", e.noise_mm, "mm"));
    }
    let mut held_out = Vec::new();
    if let Some(c) = &run.prior_choice {
        held_out.push(HeldOut {
            what: format!(
                "the prior scale's {}-fold cross-validation, grouped by {}",
                c.folds, c.grouped_by
            ),
            measured_rms_mm: None,
            expected_rms_mm: c.scores.iter().map(|s| s.held_out_rms_mm).reduce(f64::min),
        });
    }
    let report = ModelReport {
        command: "calibrate".into(),
        figures,
        warnings: calibration_warnings(r),
        held_out,
        parameters: parameter_rows(&r.params),
        rows: fitted_rows(given, &run.calibration.robot, samples, rows)?,
        outlier_rows: run.outlier_rows(rows),
        ..ModelReport::default()
    };
    Ok(finish(&run.calibration.robot, report))
}

/// The page of `fit`: `given` (with the data's stations) and the `ladder` climbed on `samples`.
pub fn for_fit(
    given: &Robot,
    samples: &[Sample],
    rows: &[usize],
    ladder: &Ladder,
) -> armcomp_core::Result<ModelReport> {
    let l = &ladder.report;
    let r = &ladder.calibration.report;
    let mut figures = vec![figure(
        "expected held-out RMS",
        "expected_rms_mm",
        l.expected_rms_mm,
        "mm",
    )];
    figures.extend(calibration_figures(r, "calibration."));
    let candidates = (l.candidates.iter())
        .map(|c| LadderRow {
            label: c.label.clone(),
            rms_mm: c.rms_mm,
            spread_mm: c.spread_mm,
            chosen: crate::ops::fit::in_choice(l, c),
            within_noise: c.within_noise,
            not_sound: c.not_sound.clone(),
        })
        .collect();
    let chosen = crate::ops::fit::choice_label(l);
    let table = LadderTable {
        candidates,
        chosen: chosen.clone(),
        reason: l.reason.clone(),
        expected_rms_mm: l.expected_rms_mm,
        folds_by: l.folds_by.clone(),
    };
    let held_out = vec![HeldOut {
        what: format!(
            "{} folds by {}, drawn {} time(s): the choice ({chosen})",
            l.folds, l.folds_by, l.repeats
        ),
        measured_rms_mm: None,
        expected_rms_mm: Some(l.expected_rms_mm),
    }];
    let mut warnings: Vec<String> = l.warning.iter().cloned().collect();
    warnings.extend(calibration_warnings(r));
    let report = ModelReport {
        command: "fit".into(),
        figures,
        warnings,
        held_out,
        ladder: Some(table),
        parameters: parameter_rows(&r.params),
        rows: fitted_rows(given, &ladder.robot, samples, rows)?,
        outlier_rows: r.outliers.iter().map(|o| rows[o.sample]).collect(),
        ..ModelReport::default()
    };
    Ok(finish(&ladder.robot, report))
}

fn figure(label: &str, key: &str, value: f64, unit: &str) -> Figure {
    Figure {
        label: label.into(),
        json_key: key.into(),
        value,
        unit: unit.into(),
    }
}

/// A calibration's figures, their keys under `prefix` in `--json`.
fn calibration_figures(r: &CalibrationReport, prefix: &str) -> Vec<Figure> {
    let mut f = vec![
        figure("rows fitted", &format!("{prefix}n_samples"), r.n_samples as f64, ""),
        figure("RMS as given", &format!("{prefix}before.rms_mm"), r.before.rms_mm, "mm"),
        figure("RMS fitted", &format!("{prefix}after.rms_mm"), r.after.rms_mm, "mm"),
        figure("max fitted", &format!("{prefix}after.max_mm"), r.after.max_mm, "mm"),
    ];
    if let Some(o) = &r.after_orientation {
        f.push(figure(
            "orientation RMS fitted",
            &format!("{prefix}after_orientation.rms_deg"),
            o.rms_deg,
            "deg",
        ));
    }
    f
}

fn calibration_warnings(r: &CalibrationReport) -> Vec<String> {
    let mut w = Vec::new();
    if !r.converged {
        w.push(format!(
            "the fit did not converge ({}): the best parameters found were written",
            r.stop_reason
        ));
    }
    w.extend(r.implausible.iter().cloned());
    w.extend(r.warnings.iter().cloned());
    w
}

fn parameter_rows(params: &[ParamResult]) -> Vec<ParameterRow> {
    params
        .iter()
        .map(|p| {
            let (scale, unit) = p.quantity.display_unit();
            ParameterRow {
                name: p.name.clone(),
                unit: unit.to_string(),
                initial: p.initial * scale,
                value: p.value * scale,
                std: (!p.fixed && p.std.is_finite()).then_some(p.std * scale),
                fixed: p.fixed,
                at_bound: p.at_bound,
                plausible: p.plausible,
            }
        })
        .collect()
}

/// The rows' residuals of `model` and of `given`, each scored as `evaluate` scores it.
fn fitted_rows(
    given: &Robot,
    model: &Robot,
    samples: &[Sample],
    rows: &[usize],
) -> armcomp_core::Result<Vec<RowResidual>> {
    let before = crate::ops::evaluate::run(given, samples)?.errors;
    let after = crate::ops::evaluate::run(model, samples)?.errors;
    Ok(residual_rows(model, samples, rows, Some(&before), &after))
}

fn residual_rows(
    model: &Robot,
    samples: &[Sample],
    rows: &[usize],
    before: Option<&[nalgebra::Vector3<f64>]>,
    after: &[nalgebra::Vector3<f64>],
) -> Vec<RowResidual> {
    let (units, tree) = (model.units(), model.tree());
    let mm = |v: &nalgebra::Vector3<f64>| [v.x * 1e3, v.y * 1e3, v.z * 1e3];
    (samples.iter().enumerate())
        .map(|(i, s)| RowResidual {
            row: rows[i],
            point: tree.points()[s.point].name.clone(),
            station: model
                .stations()
                .get(s.station)
                .map(|st| st.name.clone())
                .unwrap_or_default(),
            kind: match s.kind() {
                SampleKind::Position => "position",
                SampleKind::Plane => "plane",
                SampleKind::FixedPoint => "fixed point",
            },
            joints: (s.q.iter().zip(tree.coordinate_is_prismatic()))
                .map(|(v, p)| if *p { units.len_out(*v) } else { units.ang_out(*v) })
                .collect(),
            measured_mm: (s.kind() == SampleKind::Position).then(|| mm(&s.position)),
            before_mm: before.map(|b| mm(&b[i])),
            after_mm: mm(&after[i]),
            temperature: s.temperature,
            payload: s.payload,
        })
        .collect()
}

/// `report` with the model's name, its joint columns and the plots of its rows.
fn finish(model: &Robot, mut report: ModelReport) -> ModelReport {
    let units = model.units();
    report.robot = model.name().to_string();
    report.joint_columns = (model.tree().coordinate_names().iter())
        .zip(model.tree().coordinate_is_prismatic())
        .map(|(n, p)| {
            format!(
                "{n} ({})",
                if *p {
                    units.length.symbol()
                } else {
                    units.angle.symbol()
                }
            )
        })
        .collect();
    report.plots = plots::plots(&report);
    report
}
