//! Whether a finished fit describes a robot at all. With the noise estimated, a fit's residual
//! always matches "its" noise, so the ratio of the two says nothing: data of pure noise, positions
//! in metres labelled millimetres or joints in radians labelled degrees calibrate without a word.
//! What gives them away is the estimated noise itself, beyond what any instrument has, and how
//! little of the measured positions' spread the fitted model explains. Calibration and the model
//! ladder call [`implausibility`] on their result.

use nalgebra::Vector3;

use crate::algorithms::evaluate::model_errors;
use crate::calibrate::evidence::EvidenceReport;
use crate::data::measurement::{Sample, SampleKind};
use crate::robot::Robot;

/// The largest position noise per axis (mm) an instrument measuring an arm has: laser trackers
/// are off by hundredths of a millimetre, cameras and total stations by a millimetre or two.
/// Beyond, what the fit calls noise is the data's own mistake.
pub const INSTRUMENT_NOISE_MM: f64 = 10.0;

/// The largest orientation noise per axis (degrees) of a 6-DoF probe (a few hundredths of a
/// degree); beyond, the orientations are in another unit or of another frame.
pub const INSTRUMENT_NOISE_DEG: f64 = 5.0;

/// The smallest share of the measured positions' spread (about each station's mean) a fit must
/// explain: a model of the arm explains all of it but the noise, a model of other data almost
/// none.
pub const EXPLAINED_AT_LEAST: f64 = 0.5;

/// What is wrong with the fit of `calibrated` to `samples` and its likely cause: an estimated
/// noise (from `evidence`) beyond any instrument's, or a model that explains less than
/// [`EXPLAINED_AT_LEAST`] of the measured positions' spread. `None` for a fit that may describe
/// the robot.
pub fn implausibility(calibrated: &Robot, samples: &[Sample], evidence: Option<&EvidenceReport>) -> Option<String> {
    let positions: Vec<Sample> = (samples.iter())
        .filter(|s| s.kind() == SampleKind::Position)
        .cloned()
        .collect();
    let spread = (!positions.is_empty()).then(|| Spread::of(calibrated, &positions));
    let estimated = evidence.filter(|e| e.noise_estimated);
    if let Some(e) = estimated
        && e.noise_mm > INSTRUMENT_NOISE_MM
    {
        let what = if positions.is_empty() {
            "of the contacts".to_string()
        } else {
            "per axis".to_string()
        };
        return Some(format!(
            "the fit leaves a noise of {:.3} mm {what}, beyond any instrument's (at most {INSTRUMENT_NOISE_MM} mm): {}",
            e.noise_mm,
            spread.map_or_else(|| CONTACTS_CAUSE.to_string(), |s| s.likely_cause())
        ));
    }
    if let Some(deg) = estimated.and_then(|e| e.orientation_noise_deg)
        && deg > INSTRUMENT_NOISE_DEG
    {
        return Some(format!(
            "the fit leaves an orientation noise of {deg:.2}° per axis, beyond any 6-DoF probe's (at most \
             {INSTRUMENT_NOISE_DEG}°): the orientations look like degrees labelled rad (write `rx[deg]`, ... or \
             `roll[deg]`, ...), or they are of another frame than the robot file's marker"
        ));
    }
    if let Some(mm) = estimated.and_then(|e| e.fixed_point_noise_mm)
        && mm > INSTRUMENT_NOISE_MM
    {
        return Some(format!(
            "the fit leaves the fixed points a noise of {mm:.3} mm per axis, beyond any socket's (at most \
             {INSTRUMENT_NOISE_MM} mm): {CONTACTS_CAUSE}"
        ));
    }
    let s = spread?;
    (s.explained() < EXPLAINED_AT_LEAST).then(|| {
        format!(
            "the fitted model explains {:.0} % of the measured positions' spread (their RMS about each station's \
             mean is {:.3} mm, the residual's {:.3} mm): {}",
            100.0 * s.explained().max(0.0),
            s.measured_rms * 1e3,
            s.residual_rms * 1e3,
            s.likely_cause()
        )
    })
}

/// Why contacts fit badly, most likely first.
const CONTACTS_CAUSE: &str = "check the joint columns' units (radians labelled deg?) and that each row names the \
                              fixed point or plane it touched";

/// How the measured positions, the modelled ones and the residuals spread (m, RMS about each
/// station's mean).
#[derive(Debug, Clone, Copy)]
struct Spread {
    measured_rms: f64,
    modelled_rms: f64,
    residual_rms: f64,
}

impl Spread {
    fn of(robot: &Robot, positions: &[Sample]) -> Spread {
        let errors = model_errors(robot, positions);
        let measured: Vec<Vector3<f64>> = positions.iter().map(|s| s.position).collect();
        let modelled: Vec<Vector3<f64>> = measured.iter().zip(&errors).map(|(p, e)| p - e).collect();
        let stations: Vec<usize> = positions.iter().map(|s| s.station).collect();
        let residual_rms = (errors.iter().map(|e| e.norm_squared()).sum::<f64>() / errors.len() as f64).sqrt();
        Spread {
            measured_rms: rms_about_station_means(&measured, &stations),
            modelled_rms: rms_about_station_means(&modelled, &stations),
            residual_rms,
        }
    }

    /// The share of the measured spread the model explains (1 − residual² / spread²).
    fn explained(&self) -> f64 {
        if self.measured_rms > 0.0 {
            1.0 - (self.residual_rms / self.measured_rms).powi(2)
        } else {
            0.0
        }
    }

    /// The likely cause of a fit that does not describe the robot, from how far the measured
    /// positions spread against how far the model moves the point over the same poses.
    fn likely_cause(&self) -> String {
        let ratio = self.measured_rms / self.modelled_rms;
        // The units a length in millimetres might really be in, by their factor to millimetres.
        let units = [
            (1e3, "metres", "x[m]"),
            (100.0, "centimetres", "x[cm]"),
            (25.4, "inches", "x[in]"),
        ];
        if let Some((_, name, header)) = units
            .iter()
            .filter(|(f, _, _)| (ratio * f).ln().abs() < 2f64.ln())
            .min_by(|a, b| (ratio * a.0).ln().abs().total_cmp(&(ratio * b.0).ln().abs()))
        {
            return format!(
                "the positions spread {:.4} times as far as the model moves the point over the same poses: they look \
                 like {name} labelled in a smaller unit (write `{header}`, ...)",
                ratio
            );
        }
        if ratio > 5.0 {
            return format!(
                "the positions spread {ratio:.1} times as far as the model moves the point over the same poses: the \
                 joint values look like radians labelled deg (write `j1[rad]`, ...), or the positions are in a smaller \
                 unit than labelled"
            );
        }
        "the model does not follow the measured positions: check that the columns are the right ones (x, y, z \
         swapped, joints of another robot), that the point measured is the robot file's marker, and that the data \
         are not noise"
            .into()
    }
}

/// The RMS (m) of `points` about the mean of their station's (`stations[i]` is point `i`'s).
fn rms_about_station_means(points: &[Vector3<f64>], stations: &[usize]) -> f64 {
    let n = stations.iter().max().map_or(0, |k| k + 1);
    let mut sums = vec![(Vector3::zeros(), 0usize); n];
    for (p, &k) in points.iter().zip(stations) {
        sums[k].0 += p;
        sums[k].1 += 1;
    }
    let spread: f64 = (points.iter().zip(stations))
        .map(|(p, &k)| (p - sums[k].0 / sums[k].1 as f64).norm_squared())
        .sum();
    (spread / points.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spread_is_taken_about_each_stations_mean() {
        // Two stations, each two points 2 m apart about its own mean: 1 m from it each.
        let points = [
            Vector3::new(-1.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(100.0, 1.0, 0.0),
            Vector3::new(100.0, -1.0, 0.0),
        ];
        assert!((rms_about_station_means(&points, &[0, 0, 1, 1]) - 1.0).abs() < 1e-12);
    }

    fn spread(measured_rms: f64, modelled_rms: f64, residual_rms: f64) -> Spread {
        Spread {
            measured_rms,
            modelled_rms,
            residual_rms,
        }
    }

    #[test]
    fn the_explained_share_follows_its_definition() {
        assert!((spread(2.0, 2.0, 1.0).explained() - 0.75).abs() < 1e-12);
        assert_eq!(spread(0.0, 1.0, 1.0).explained(), 0.0);
    }

    #[test]
    fn the_likely_cause_names_the_unit_the_ratio_gives_away() {
        assert!(spread(1e-3, 1.0, 1.0).likely_cause().contains("metres"));
        assert!(spread(1.0 / 25.4, 1.0, 1.0).likely_cause().contains("inches"));
        assert!(spread(1.0 / 100.0, 1.0, 1.0).likely_cause().contains("centimetres"));
        assert!(spread(50.0, 1.0, 1.0).likely_cause().contains("radians labelled deg"));
        assert!(
            spread(1.5, 1.0, 1.0)
                .likely_cause()
                .contains("columns are the right ones")
        );
    }
}
