//! What rows of every kind measure under a model: the error of a model fitted on some rows on
//! the rows it was not fitted on (what the ladder and the diagnosis score models by), and
//! contacts as the positions they measure (what a residual predictor learns from).

use nalgebra::Vector3;

use crate::algorithms::evaluate::position_errors;
use crate::calibrate::contact_gaps;
use crate::data::measurement::{Sample, SampleKind};
use crate::error::Result;
use crate::robot::Robot;

/// The held-out error of each of `test`'s samples under `model`, fitted on `train` (the held-out
/// stations registered by the caller, [`register_held_out_stations`](crate::calibrate::register_held_out_stations)):
/// - a measured position: its 3-D error;
/// - a plane contact: its height above the plane the training rows identified, along the
///   plane's normal;
/// - a fixed-point contact: its modelled point less where the training contacts with that
///   point put it (the mean of their modelled points, the least-squares estimate of the point
///   for that model).
///
/// `None` for a sample nothing in `train` locates: a plane or fixed point no training row
/// touched.
pub fn held_out_errors(model: &Robot, train: &[Sample], test: &[Sample]) -> Result<Vec<Option<Vector3<f64>>>> {
    let errors = position_errors(model, test);
    let planes = if test.iter().any(|s| s.plane.is_some()) {
        Some(contact_gaps(model, test)?)
    } else {
        None
    };
    let centres = fixed_point_centres(model, train);
    Ok(test
        .iter()
        .enumerate()
        .map(|(k, s)| match (&s.fixed_point, &planes) {
            (Some(name), _) => centres
                .iter()
                .find(|(n, _)| n == name)
                // The modelled point is the sample's (unused) position less its error.
                .map(|(_, c)| s.position - errors[k] - c),
            (None, Some((gaps, names))) if s.plane.is_some() => match &gaps[k] {
                // A plane the model does not hold was fitted to the held-out rows themselves.
                Some(g) if !names[g.plane].1 => Some(g.normal * g.height),
                _ => None,
            },
            _ => Some(errors[k]),
        })
        .collect())
}

/// Where `model` puts each fixed point `samples` touch: the mean of its contacts' modelled
/// points (measurement frame of their station).
fn fixed_point_centres(model: &Robot, samples: &[Sample]) -> Vec<(String, Vector3<f64>)> {
    if samples.iter().all(|s| s.fixed_point.is_none()) {
        return Vec::new();
    }
    let errors = position_errors(model, samples);
    let mut sums: Vec<(String, Vector3<f64>, usize)> = Vec::new();
    for (s, e) in samples.iter().zip(&errors) {
        let Some(name) = &s.fixed_point else { continue };
        let p = s.position - e;
        match sums.iter_mut().find(|(n, _, _)| n == name) {
            Some((_, sum, n)) => {
                *sum += p;
                *n += 1;
            }
            None => sums.push((name.clone(), p, 1)),
        }
    }
    sums.into_iter().map(|(n, sum, k)| (n, sum / k as f64)).collect()
}

/// `samples` with every contact turned into the position it measures under `model`: a
/// fixed-point contact into where `model`'s contacts with that point put it (the mean of their
/// modelled points), a plane contact into its modelled point moved along the normal onto the
/// plane `model` holds (the plane fitted to the contacts when it holds none). What `model`
/// leaves of them is then a 3-D error, as of measured positions, which a residual predictor
/// can learn. Measured positions are kept as they are.
pub fn contacts_as_positions(model: &Robot, samples: &[Sample]) -> Result<Vec<Sample>> {
    let errors = position_errors(model, samples);
    let centres = fixed_point_centres(model, samples);
    let gaps = if samples.iter().any(|s| s.plane.is_some()) {
        contact_gaps(model, samples)?.0
    } else {
        vec![None; samples.len()]
    };
    Ok(samples
        .iter()
        .zip(errors)
        .zip(gaps)
        .map(|((s, e), gap)| {
            let modelled = s.position - e;
            let position = match (&s.fixed_point, gap) {
                (Some(name), _) => centres.iter().find(|(n, _)| n == name).map(|(_, c)| *c),
                (None, Some(g)) => Some(modelled - g.normal * g.height),
                (None, None) => None,
            };
            match position {
                Some(position) => Sample {
                    position,
                    fixed_point: None,
                    plane: None,
                    ..s.clone()
                },
                None => s.clone(),
            }
        })
        .collect())
}

/// The kind of held-out error [`held_out_errors`] gives sample `s`: `position`, `plane height`
/// or `fixed-point distance`.
pub fn kind_of(s: &Sample) -> &'static str {
    scored_as(s.kind())
}

/// What a held-out row of `kind` is scored by.
fn scored_as(kind: SampleKind) -> &'static str {
    match kind {
        SampleKind::Position => "position",
        SampleKind::Plane => "plane height",
        SampleKind::FixedPoint => "fixed-point distance",
    }
}

/// The kinds of held-out error `samples` are scored by ([`kind_of`]), `+`-joined for mixed
/// data.
pub fn scored_by(samples: &[Sample]) -> String {
    kinds(samples).join(" + ")
}

/// The kinds of `samples` ([`kind_of`]), each once, positions first.
pub fn kinds(samples: &[Sample]) -> Vec<&'static str> {
    (SampleKind::ALL.into_iter())
        .filter(|&k| samples.iter().any(|s| s.kind() == k))
        .map(scored_as)
        .collect()
}

/// Whether every sample measures a position (no fixed-point or plane contacts): the rows a
/// residual predictor, which learns 3-D errors, can learn from.
pub fn measures_positions(samples: &[Sample]) -> bool {
    samples.iter().all(|s| s.kind() == SampleKind::Position)
}
