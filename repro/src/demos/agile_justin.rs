//! The Agile Justin calibration table (`armcomp demo agile-justin`) as demo tables, so that its
//! HTML report is the other demos' report: each step's held-out errors are a row beside the
//! paper's mean, the frames-only step is the "before" and the best step the "after" of the
//! histograms and per-target plots.

use nalgebra::Vector3;

use crate::agile_justin::{KfoldErrors, MEASUREMENT_STD, STEPS, StepResult};

use super::{PaperMetric, PaperValue, Row, Table};

/// The paper's mean (mm) for the step labelled `step`, when the paper has that step.
fn paper_mean(step: &str) -> Option<PaperValue> {
    STEPS.iter().find(|s| s.label == step).map(|s| PaperValue {
        mean_mm: s.published.mean_mm,
        variance_mm2: None,
    })
}

/// A table of one evaluation: `rows` are (step label, poses fitted, seconds, held-out errors).
fn table(title: String, setup: String, rows: Vec<(&str, usize, f64, &[Vector3<f64>])>) -> Table {
    let noise_mm = MEASUREMENT_STD * 1e3;
    Table {
        title,
        setup,
        noise_mm,
        noise_mean_abs_z_mm: noise_mm * (2.0 / std::f64::consts::PI).sqrt(),
        paper_metric: PaperMetric::Mean3d,
        rows: rows
            .into_iter()
            .map(|(step, poses, seconds, errors)| Row::from_errors(step, paper_mean(step), (poses, seconds), errors))
            .collect(),
    }
}

/// The demo's tables: the fixed split's held-out errors per step (`steps`, from
/// `agile_justin::step_table`, fitted on `train_poses` poses, `seed` the split's) and, when
/// given, the k-fold held-out errors pooled over `folds` folds. The measurement noise shown is
/// the tracker noise the fits assume, not a measured one.
pub fn tables(
    poses: usize,
    train_poses: usize,
    seed: u64,
    steps: &[StepResult],
    kfold: Option<(usize, &[KfoldErrors])>,
) -> Vec<Table> {
    let held_out = poses - train_poses;
    let mut out = vec![table(
        format!("Agile Justin, fixed split: held-out errors of each calibration step (seed {seed})"),
        format!(
            "{poses} real poses, 2 hand markers each; steps identified in turn on {train_poses} poses, errors at the \
             {} markers of the {held_out} held-out poses; noise is the tracker noise the fits assume",
            2 * held_out
        ),
        steps
            .iter()
            .map(|s| (s.step.as_str(), train_poses, s.seconds, s.test_errors.as_slice()))
            .collect(),
    )];
    if let Some((folds, rows)) = kfold {
        out.push(table(
            format!("Agile Justin, {folds}-fold: held-out errors of each step, every pose held out once"),
            format!(
                "{poses} real poses, 2 hand markers each; in each of {folds} folds the steps are identified on the \
                 other folds' poses; errors pooled over the folds in fold order, training seconds summed"
            ),
            rows.iter()
                .map(|r| (r.step.as_str(), r.train_poses, r.seconds, r.test_errors.as_slice()))
                .collect(),
        ));
    }
    out
}
