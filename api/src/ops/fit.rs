//! `fit`: the model ladder of [`armcomp_core::analysis::ladder`] with the predictor named as the command
//! line names it, and its JSON report.

use armcomp_core::Robot;
use armcomp_core::analysis::ladder::{CandidateScore, Ladder, LadderParams, LadderReport, climb};
use armcomp_core::calibrate::CalibrationParams;
use armcomp_core::calibrate::FitsProgress;
use armcomp_core::calibrate::plausibility::implausibility;
use armcomp_core::data::measurement::MeasurementSet;
use armcomp_core::support::cancel::Cancel;

/// How `fit` is asked to choose.
#[derive(Debug, Clone, PartialEq)]
pub struct FitParams {
    /// The declared noise per axis (mm); `None` estimates it with every fit.
    pub noise_mm: Option<f64>,
    /// The declared orientation noise per axis (degrees) of poses and plane contacts' tilts;
    /// the noises are declared only when this is given too (or the robot measures no poses),
    /// as for `calibrate`.
    pub noise_deg: Option<f64>,
    /// Outer folds.
    pub folds: usize,
    /// How many times the folds are drawn (each draw with its own seed); `None`:
    /// [`default_repeats`] for the rows.
    pub repeats: Option<usize>,
    /// Seed of the folds.
    pub seed: u64,
    /// A group per sample: folds hold out whole groups (`None`: whole poses).
    pub fold_groups: Option<Vec<usize>>,
    /// The residual predictor to try (`gp`, `mlp`, ...; `None` for none).
    pub predictor: Option<String>,
    /// Ends the cross-validation with the rungs fitted so far, the choice among them fitted on
    /// all rows (a further request stops that too).
    pub cancel: Cancel,
}

/// Rows from which the folds are drawn once by default: the scores of folds that large move by
/// a few hundredths of their spread from one draw to the next, and each draw costs a whole
/// ladder of fits.
pub const ONE_DRAW_FROM_ROWS: usize = 2000;

/// How many times the folds are drawn by default for `rows` rows: three, so that the choice
/// does not flip with one draw's folds, or once from [`ONE_DRAW_FROM_ROWS`] rows.
pub fn default_repeats(rows: usize) -> usize {
    if rows >= ONE_DRAW_FROM_ROWS { 1 } else { 3 }
}

/// Climbs the ladder for `robot` on `data`, the robot given the data's stations (each
/// station's frame registered in closed form and refined with every fit); `progress` sees
/// every fit done.
pub fn run(
    robot: &Robot,
    data: &MeasurementSet,
    params: FitParams,
    progress: &(dyn Fn(FitsProgress) + Sync),
) -> armcomp_core::Result<Ladder> {
    crate::ops::calibrate::check_noises(params.noise_mm, params.noise_deg)?;
    let predictor = params
        .predictor
        .as_deref()
        .map(crate::ops::learn::default_predictor)
        .transpose()?;
    let calibration = CalibrationParams {
        measurement_std: params.noise_mm.unwrap_or(0.1) * 1e-3,
        orientation_std: params.noise_deg.unwrap_or(0.1).to_radians(),
        seed: params.seed,
        cancel: params.cancel,
        ..CalibrationParams::default()
    };
    let noise_declared = params.noise_mm.is_some() && (params.noise_deg.is_some() || !robot.measures_pose());
    let ladder = LadderParams {
        folds: params.folds,
        repeats: params.repeats.unwrap_or_else(|| default_repeats(data.samples.len())),
        seed: params.seed,
        fold_groups: params.fold_groups,
        predictor,
        ..LadderParams::new(calibration, noise_declared)
    };
    let adopted = crate::with_stations(robot, data)?;
    let samples = &data.samples;
    let mut ladder = climb(adopted.as_ref().unwrap_or(robot), samples, &ladder, progress)?;
    ladder.calibration.report.implausible =
        implausibility(&ladder.calibration.robot, samples, Some(&ladder.report.evidence));
    Ok(ladder)
}

/// The report as `armcomp fit --json` prints it: the ladder with the chosen rung's calibration
/// report as `calibration`.
pub fn to_json(ladder: &Ladder) -> serde_json::Value {
    // Both serialise plain numbers, strings and lists: they cannot fail.
    let mut value = serde_json::to_value(&ladder.report).expect("the ladder serialises");
    value["calibration"] = serde_json::to_value(&ladder.calibration.report).expect("the report serialises");
    value
}

/// Whether the ladder's candidate `c` is its choice or a member of the chosen stack.
pub fn in_choice(r: &LadderReport, c: &CandidateScore) -> bool {
    c.candidate == r.chosen
        || (c.candidate.rung == r.chosen.rung
            && c.candidate.predictor == r.chosen.predictor
            && r.stack.iter().any(|m| m.prior == c.candidate.prior))
}

/// The choice in words: the candidate's label, or for a stack its level and the weighted
/// members (`geometry, the weighted mean of 0.62 × evidence per group + 0.38 × file ×10`).
pub fn choice_label(r: &LadderReport) -> String {
    if r.stack.is_empty() {
        return r.chosen.label();
    }
    let members: Vec<String> = r
        .stack
        .iter()
        .map(|m| format!("{:.2} × {}", m.weight, m.label))
        .collect();
    format!(
        "{}, the weighted mean of {}{}",
        r.chosen.rung.label(),
        members.join(" + "),
        if r.chosen.predictor { ", + predictor" } else { "" }
    )
}

/// Group numbers, one per sample, from the values of a column per data row (`values`, indexed
/// by row) and each sample's row: equal values, one group.
pub fn groups_of(values: &[String], rows: &[usize]) -> Vec<usize> {
    let mut names: Vec<&String> = Vec::new();
    rows.iter()
        .map(|&r| {
            let v = &values[r];
            names.iter().position(|n| *n == v).unwrap_or_else(|| {
                names.push(v);
                names.len() - 1
            })
        })
        .collect()
}

/// The folds' groups as `--group-by` gives them, from the measurement CSVs `tables` (each
/// text with its path, their data rows numbered on from one to the next): the grouping's name
/// and each of `rows`' group. `group_by` names a column, or `COLUMN:N` cuts a numeric column
/// into N blocks of consecutive values; without it, the first set-up column (`session`,
/// `setup`, ...) every table has; `None` when there is none.
pub fn groups_by_column(
    group_by: Option<&str>,
    tables: &[(&str, &std::path::Path)],
    rows: &[usize],
) -> armcomp_core::Result<Option<(String, Vec<usize>)>> {
    use armcomp_core::data::measurement::{column_values, set_up_column, split_header};
    let invalid = |what: String, reason: String| armcomp_core::Error::InvalidArgument { what, reason };
    // `COLUMN:N`: blocks of a numeric column; a name that merely holds a colon is whole.
    let blocks_of_column = group_by
        .and_then(|g| g.rsplit_once(':'))
        .and_then(|(c, n)| Some((c.trim().to_string(), n.trim().parse::<usize>().ok()?)));
    let (column, blocks) = match blocks_of_column {
        Some((c, n)) => (Some(c), Some(n)),
        None => (group_by.map(str::to_string), None),
    };
    let column = match column {
        Some(c) => c,
        None => {
            let mut found = None;
            for &(text, file) in tables {
                let c = set_up_column(text, file)?;
                if c.is_none() || (found.is_some() && found != c) {
                    return Ok(None);
                }
                found = c;
            }
            match found {
                Some(c) => c.to_string(),
                None => return Ok(None),
            }
        }
    };
    let bare = split_header(&column).0;
    if let Some(what) = [("fixed_point", "fixed point"), ("plane", "plane")]
        .iter()
        .find_map(|&(c, what)| (bare == c).then_some(what))
    {
        return Err(invalid(
            format!("--group-by {column}"),
            format!(
                "a fold that held out every row of a {what} would leave its position unknown to the rows it is \
                 fitted on, so nothing could score it; fold by pose (leave --group-by out) or by a set-up column"
            ),
        ));
    }
    let mut values = Vec::new();
    let mut sources = Vec::new();
    for &(text, file) in tables {
        let v = column_values(text, file, &column)?;
        sources.extend((0..v.len()).map(|r| (file, r)));
        values.extend(v);
    }
    let Some(blocks) = blocks else {
        return Ok(Some((column, groups_of(&values, rows))));
    };
    if blocks < 2 {
        return Err(invalid(
            format!("--group-by {column}:{blocks}"),
            "expected at least 2 blocks to hold one out".into(),
        ));
    }
    let numbers = rows
        .iter()
        .map(|&r| {
            let (file, row) = sources[r];
            values[r].parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
                invalid(
                    format!("{}: data row {row}, column `{column}`", file.display()),
                    format!(
                        "`{}` is not a number; --group-by {column}:{blocks} cuts a numeric column into blocks",
                        values[r]
                    ),
                )
            })
        })
        .collect::<armcomp_core::Result<Vec<f64>>>()?;
    let name = format!("`{column}` in {blocks} blocks");
    Ok(Some((name, blocks_of(&numbers, blocks))))
}

/// Block numbers, one per sample, cutting the samples' `values` (a time, a temperature) into
/// `blocks` runs of consecutive values with as many samples each; equal values share a block,
/// so a block may hold a few more.
pub fn blocks_of(values: &[f64], blocks: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut out = vec![0; values.len()];
    let mut block = 0;
    for (rank, &i) in order.iter().enumerate() {
        // A tie stays in the block its first value opened.
        if rank > 0 && values[i] != values[order[rank - 1]] {
            block = rank * blocks / values.len();
        }
        out[i] = block;
    }
    out
}
