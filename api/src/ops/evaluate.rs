//! `evaluate`: position errors of a model on measurements, overall and per measured point.

use std::collections::BTreeMap;

use armcomp_core::Robot;
use armcomp_core::algorithms::evaluate::{
    AngleStats, ErrorStats, FixedPointEvaluation, StationStats, evaluate_fixed_points, orientation_errors, per_station,
    position_errors,
};
use armcomp_core::calibrate::{PlaneEvaluation, evaluate_planes};
use armcomp_core::data::measurement::{
    MeasurementSet, RowSelection, Sample, SampleKind, csv_text, joint_header, joint_row,
};
use nalgebra::Vector3;

/// How far a model is from measurements.
#[derive(Debug, Clone)]
pub struct EvaluationReport {
    /// Over every sample.
    pub stats: ErrorStats,
    /// Per measured point by name, when the samples measure several.
    pub per_point: BTreeMap<String, ErrorStats>,
    /// Over every sample with a measured orientation, when the robot measures poses.
    pub orientation: Option<AngleStats>,
    /// Measured minus modelled position of every sample, measurement frame (m); for a
    /// fixed-point sample, the mean of its fixed point's modelled points minus its own.
    pub errors: Vec<Vector3<f64>>,
    /// The fixed points' spreads and the known distances, for fixed-point measurements.
    pub fixed_points: Option<FixedPointEvaluation>,
    /// The out-of-plane distances and tilts per plane, for plane contacts.
    pub planes: Option<PlaneEvaluation>,
    /// Per station, when the robot has several (see [`per_station`]).
    pub per_station: Vec<StationStats>,
    /// The stations whose frame was registered on these data (empty name: the one station).
    pub registered: Vec<String>,
}

/// Registers the measurement frames of `stations` (indices into the robot's stations; 0 for
/// a robot measured from one place) on `samples` in closed form, then evaluates `robot` on
/// them: what `armcomp evaluate --register` scores, and what it does for stations the model
/// does not know. The report names the stations registered (an empty name: the one frame).
pub fn run_registered(
    robot: &mut Robot,
    samples: &[Sample],
    stations: &[usize],
) -> armcomp_core::Result<EvaluationReport> {
    register_then_run(robot, samples, samples, stations)
}

/// [`run_registered`] with the frames registered on `stationing` (a station's stationing points)
/// and the model evaluated on `samples`, other rows of the same stations.
pub fn register_then_run(
    robot: &mut Robot,
    stationing: &[Sample],
    samples: &[Sample],
    stations: &[usize],
) -> armcomp_core::Result<EvaluationReport> {
    let failed = armcomp_core::calibrate::register_stations_on_poses(robot, stationing, stations)?;
    if let Some(&k) = failed.first() {
        return Err(armcomp_core::Error::InvalidArgument {
            what: format!(
                "station {}",
                robot.stations().get(k).map_or("of the data", |s| s.name.as_str())
            ),
            reason: "cannot be registered: its measured points do not span a plane (measure at least three poses \
                     that are not in line)"
                .into(),
        });
    }
    let mut report = run(robot, samples)?;
    report.registered = (stations.iter())
        .map(|&k| robot.stations().get(k).map_or_else(String::new, |s| s.name.clone()))
        .collect();
    Ok(report)
}

/// [`register_then_run`] with the stationing points given as rows of `set`, the data of all of
/// its stations: the stations of the evaluated rows (`rows`, or all of them, without those of
/// `on`) are registered on the rows `on` selects, and the model is evaluated on the others.
/// Returns those rows and the report. Every station evaluated needs stationing rows.
pub fn register_on_then_run(
    robot: &mut Robot,
    set: &MeasurementSet,
    on: &RowSelection,
    rows: Option<&RowSelection>,
) -> armcomp_core::Result<(MeasurementSet, EvaluationReport)> {
    let invalid = |reason: String| armcomp_core::Error::InvalidArgument {
        what: "--register-on".into(),
        reason,
    };
    let stationing = set.rows_where(|r| on.contains(r));
    let evaluated = set.rows_where(|r| !on.contains(r) && rows.is_none_or(|s| s.contains(r)));
    if evaluated.samples.is_empty() {
        return Err(invalid(
            "they take every row selected; keep some rows to evaluate on".into(),
        ));
    }
    let mut stations: Vec<usize> = evaluated.samples.iter().map(|s| s.station).collect();
    stations.sort_unstable();
    stations.dedup();
    if let Some(&k) = (stations.iter()).find(|&&k| stationing.samples.iter().all(|s| s.station != k)) {
        let name = robot.stations().get(k).map_or("of the data", |s| s.name.as_str());
        return Err(invalid(format!(
            "station {name} has none; give each station's stationing points"
        )));
    }
    let report = register_then_run(robot, &stationing.samples, &evaluated.samples, &stations)?;
    Ok((evaluated, report))
}

/// Evaluates `robot` (with its fitted predictor) on `samples`.
pub fn run(robot: &Robot, samples: &[Sample]) -> armcomp_core::Result<EvaluationReport> {
    let mut errors = position_errors(robot, samples);
    let fixed_points = evaluate_fixed_points(robot, samples, &mut errors);
    let planes = evaluate_planes(robot, samples, &mut errors)?;
    // Data mixing measured positions with fixed points or plane contacts: the figures are the
    // measured positions', the contacts have their own.
    // Per point and per station too, when there are measured positions to give them.
    let (kept_samples, kept_errors): (Vec<Sample>, Vec<Vector3<f64>>) = (samples.iter().zip(&errors))
        .filter(|(s, _)| s.kind() == SampleKind::Position)
        .map(|(s, e)| (s.clone(), *e))
        .unzip();
    let (samples, measured) = if kept_errors.is_empty() {
        (samples, errors.as_slice())
    } else {
        (kept_samples.as_slice(), kept_errors.as_slice())
    };
    let stats = ErrorStats::from_errors(measured);
    let mut points: Vec<usize> = samples.iter().map(|s| s.point).collect();
    points.sort_unstable();
    points.dedup();
    let per_point = if points.len() > 1 {
        points
            .iter()
            .map(|&p| {
                let e: Vec<_> = measured
                    .iter()
                    .zip(samples)
                    .filter(|(_, s)| s.point == p)
                    .map(|(e, _)| *e)
                    .collect();
                (robot.tree().points()[p].name.clone(), ErrorStats::from_errors(&e))
            })
            .collect()
    } else {
        BTreeMap::new()
    };
    let per_station = per_station(robot, samples, measured);
    let angles: Vec<f64> = if robot.measures_pose() {
        orientation_errors(robot, samples).into_iter().flatten().collect()
    } else {
        Vec::new()
    };
    Ok(EvaluationReport {
        stats,
        per_point,
        orientation: (!angles.is_empty()).then(|| AngleStats::from_angles(&angles)),
        per_station,
        registered: Vec::new(),
        errors,
        fixed_points,
        planes,
    })
}

impl EvaluationReport {
    /// The report as `armcomp evaluate --json` prints it.
    pub fn to_json(&self) -> serde_json::Value {
        let mut value = serde_json::to_value(self.stats).expect("the statistics serialise");
        if !self.per_point.is_empty() {
            value["per_point"] = serde_json::to_value(&self.per_point).expect("the statistics serialise");
        }
        if let Some(o) = &self.orientation {
            value["orientation"] = serde_json::to_value(o).expect("the statistics serialise");
        }
        if let Some(f) = &self.fixed_points {
            value["fixed_points"] = serde_json::to_value(f).expect("the statistics serialise");
        }
        if let Some(p) = &self.planes {
            value["planes"] = serde_json::to_value(p).expect("the statistics serialise");
        }
        if !self.per_station.is_empty() {
            value["per_station"] = serde_json::to_value(&self.per_station).expect("the statistics serialise");
        }
        if !self.registered.is_empty() {
            value["registered_stations"] = self.registered.clone().into();
        }
        value
    }

    /// The residuals CSV of `armcomp evaluate --residuals`: one row per sample, in file order.
    pub fn residuals_csv(&self, robot: &Robot, samples: &[Sample]) -> String {
        let units = robot.units();
        let lu = units.length.symbol();
        let mut header: Vec<String> = vec!["sample".into(), "point".into()];
        header.extend(joint_header(robot.tree(), units));
        header.extend(["x_err", "y_err", "z_err", "err"].map(|c| format!("{c}[{lu}]")));
        let rows = samples.iter().zip(&self.errors).enumerate().map(|(i, (s, e))| {
            let mut row = vec![(i + 1).to_string(), robot.tree().points()[s.point].name.clone()];
            row.extend(joint_row(&s.q, robot.tree(), units));
            row.extend([e.x, e.y, e.z, e.norm()].map(|v| units.len_out(v).to_string()));
            row
        });
        csv_text(std::iter::once(header).chain(rows))
    }
}
