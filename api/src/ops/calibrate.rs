//! `calibrate`: the prior choice around [`armcomp_core::calibrate::calibrate`] and its JSON report.

use armcomp_core::Robot;
use armcomp_core::analysis::prior_choice::{DEFAULT_GRID, PriorChoice, choose_prior_scale};
use armcomp_core::calibrate::evidence::{EvidenceParams, EvidenceReport, Grouping, calibrate_with_evidence};
use armcomp_core::calibrate::plausibility::implausibility;
use armcomp_core::calibrate::{Calibration, CalibrationParams, FitsProgress, IterationInfo, calibrate};
use armcomp_core::data::measurement::Sample;
use armcomp_core::data::split::{FoldBy, FoldPlan};

/// How strongly the robot file's priors hold the parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Prior {
    /// A factor on their standard deviations (infinite: no priors).
    Scale(f64),
    /// Chosen by 5-fold cross-validation on the calibration data alone.
    Auto,
    /// Factors chosen by the evidence (type-II maximum likelihood) of the calibration data:
    /// one per chain parameter (`evidence`) or one per group of parameters
    /// (`evidence-groups`).
    Evidence(Grouping),
}

impl std::str::FromStr for Prior {
    type Err = String;

    /// `evidence`, `auto`, `none` or a positive factor.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "auto" => Ok(Prior::Auto),
            "evidence" => Ok(Prior::Evidence(Grouping::PerParameter)),
            "evidence-groups" => Ok(Prior::Evidence(Grouping::Groups)),
            "none" => Ok(Prior::Scale(f64::INFINITY)),
            t => match t.parse::<f64>() {
                Ok(v) if v > 0.0 => Ok(Prior::Scale(v)),
                _ => Err(format!(
                    "expected `evidence`, `evidence-groups`, `auto`, `none` or a positive factor on the priors' standard deviations, got `{t}`"
                )),
            },
        }
    }
}

/// Refuses a declared noise no tracker has: per axis from a nanometre to a metre, and an
/// orientation noise from a micro-degree to 90°. Beyond, the number is in another unit or a
/// slip: a noise of 10⁸ mm leaves no parameter determined, one of 0 or NaN weighs the data
/// without bound.
pub fn check_noises(noise_mm: Option<f64>, noise_deg: Option<f64>) -> armcomp_core::Result<()> {
    let check = |what: &str, value: Option<f64>, (low, high): (f64, f64), unit: &str| match value {
        Some(v) if !(low..=high).contains(&v) => Err(armcomp_core::Error::InvalidArgument {
            what: what.into(),
            reason: format!(
                "expected a noise per axis from {low:e} to {high} {unit}, got {}",
                armcomp_core::support::text::number(v)
            ),
        }),
        _ => Ok(()),
    };
    check("--noise-mm", noise_mm, (1e-6, 1e3), "mm")?;
    check("--noise-deg", noise_deg, (1e-6, 90.0), "degrees")
}

/// A calibration and, for [`Prior::Auto`], the cross-validation that chose its prior scale.
#[derive(Debug)]
pub struct CalibrationRun {
    /// The identified robot and its report.
    pub calibration: Calibration,
    /// The prior choice, when it was made from the data by cross-validation.
    pub prior_choice: Option<PriorChoice>,
    /// The noise and prior scales chosen by the evidence, when any was.
    pub evidence: Option<EvidenceReport>,
}

/// `samples` and their data `rows` without the data rows `drop` (the gross errors a first fit
/// found, for a second without them).
pub fn without_rows(samples: &[Sample], rows: &[usize], drop: &[usize]) -> (Vec<Sample>, Vec<usize>) {
    (samples.iter().zip(rows))
        .filter(|(_, r)| !drop.contains(r))
        .map(|(s, &r)| (s.clone(), r))
        .unzip()
}

impl CalibrationRun {
    /// The report as `armcomp calibrate --json` prints it: the calibration report with
    /// `prior_choice`, `evidence` and `outlier_rows` (the data rows, as `--rows` counts them, of
    /// its gross errors; `rows` gives each sample's row).
    pub fn to_json(&self, rows: &[usize]) -> serde_json::Value {
        // Both serialise plain numbers, strings and lists: they cannot fail.
        let mut value = serde_json::to_value(&self.calibration.report).expect("the report serialises");
        value["prior_choice"] = serde_json::to_value(&self.prior_choice).expect("the prior choice serialises");
        value["evidence"] = serde_json::to_value(&self.evidence).expect("the evidence report serialises");
        value["outlier_rows"] = self.outlier_rows(rows).into();
        value
    }
}

impl CalibrationRun {
    /// The data rows of the gross errors, largest first; `rows` gives each sample's row.
    pub fn outlier_rows(&self, rows: &[usize]) -> Vec<usize> {
        self.calibration
            .report
            .outliers
            .iter()
            .map(|o| rows[o.sample])
            .collect()
    }
}

/// What `calibrate` chooses besides the parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Choices {
    /// How the prior scale is set.
    pub prior: Prior,
    /// Whether the noise is the declared `params.measurement_std` (else estimated with the fit).
    pub noise_declared: bool,
    /// Whole groups held out by [`Prior::Auto`]'s cross-validation (a column's name and each
    /// sample's group); `None`: by station for data from several, else by pose.
    pub fold_groups: Option<(String, Vec<usize>)>,
}

/// Calibrates `robot` on `samples` with `params` and the `choices`. `fits` sees every fit of
/// the prior's cross-validation, `observer` every iteration of the final fit.
pub fn run(
    robot: &Robot,
    samples: &[Sample],
    mut params: CalibrationParams,
    choices: Choices,
    fits: &(dyn Fn(FitsProgress) + Sync),
    observer: &mut dyn FnMut(&IterationInfo),
) -> armcomp_core::Result<CalibrationRun> {
    armcomp_core::calibrate::check_station_rows(robot, samples)?;
    let Choices {
        prior,
        noise_declared,
        fold_groups,
    } = choices;
    let prior_choice = match prior {
        Prior::Scale(s) => {
            params.prior_scale = s;
            None
        }
        Prior::Evidence(_) => None,
        Prior::Auto => {
            let plan = FoldPlan {
                k: 5,
                seed: 0,
                by: FoldBy::choose(samples, fold_groups),
            };
            let choice = choose_prior_scale(robot, samples, &params, &DEFAULT_GRID, &plan, fits)?;
            if choice.interrupted {
                // The final fit at the best scale scored, which only a further request stops.
                params.cancel = params.cancel.renewed();
            }
            params.prior_scale = choice.scale;
            Some(choice)
        }
    };
    let evidence = EvidenceParams {
        estimate_noise: !noise_declared,
        estimate_priors: matches!(prior, Prior::Evidence(_)),
        grouping: match prior {
            Prior::Evidence(g) => g,
            _ => Grouping::PerParameter,
        },
        ..EvidenceParams::default()
    };
    let (mut calibration, evidence) = if evidence.estimate_noise || evidence.estimate_priors {
        let (c, e) = calibrate_with_evidence(robot, samples, &params, &evidence, observer)?;
        (c, Some(e))
    } else {
        (calibrate(robot, samples, &params, observer)?, None)
    };
    calibration.report.implausible = implausibility(&calibration.robot, samples, evidence.as_ref());
    Ok(CalibrationRun {
        calibration,
        prior_choice,
        evidence,
    })
}
