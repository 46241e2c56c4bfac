//! Train/test splits and k-fold partitions of measurements, by pose, by station or by a
//! named group.
//!
//! Samples that share a configuration (several markers measured at one pose) always stay on
//! the same side, so a held-out score never sees a pose that was trained on. Data from
//! several stations are folded by station ([`folds`]): poses of one set-up share its frame's
//! errors and whatever drifted during it, so random folds over them score optimistically.

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;

use crate::data::measurement::Sample;
use crate::error::{Error, Result};

/// Sample indices of one split.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Split {
    /// Indices used to fit.
    pub train: Vec<usize>,
    /// Indices held out.
    pub test: Vec<usize>,
}

/// Groups of sample indices measured at the same configuration, in file order.
pub fn pose_groups(samples: &[Sample]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, s) in samples.iter().enumerate() {
        match groups.last_mut() {
            Some(g) if samples[g[0]].q == s.q => g.push(i),
            _ => groups.push(vec![i]),
        }
    }
    groups
}

/// The pose groups in an order shuffled by `seed`.
fn shuffled_groups(samples: &[Sample], seed: u64) -> Vec<Vec<usize>> {
    let mut groups = pose_groups(samples);
    groups.shuffle(&mut StdRng::seed_from_u64(seed));
    groups
}

fn flatten(groups: &[Vec<usize>]) -> Vec<usize> {
    let mut v: Vec<usize> = groups.iter().flatten().copied().collect();
    v.sort_unstable();
    v
}

/// Holds out `test_fraction` of the poses (rounded, at least one on each side), chosen by `seed`.
pub fn holdout(samples: &[Sample], test_fraction: f64, seed: u64) -> Result<Split> {
    if !(test_fraction > 0.0 && test_fraction < 1.0) {
        return Err(Error::InvalidArgument {
            what: "held-out fraction".into(),
            reason: format!("must be between 0 and 1 (exclusive), got {test_fraction}"),
        });
    }
    let groups = shuffled_groups(samples, seed);
    if groups.len() < 2 {
        return Err(Error::InvalidArgument {
            what: "poses".into(),
            reason: format!("a train/test split needs at least 2, the data has {}", groups.len()),
        });
    }
    let n_test = ((groups.len() as f64 * test_fraction).round() as usize).clamp(1, groups.len() - 1);
    Ok(Split {
        test: flatten(&groups[..n_test]),
        train: flatten(&groups[n_test..]),
    })
}

/// `k` folds over the poses shuffled by `seed`; fold `i` holds out every `k`-th pose group.
pub fn kfold(samples: &[Sample], k: usize, seed: u64) -> Result<Vec<Split>> {
    let groups = shuffled_groups(samples, seed);
    if k < 2 || k > groups.len() {
        return Err(Error::InvalidArgument {
            what: "folds".into(),
            reason: format!("k-fold needs 2 ≤ k ≤ number of poses ({}), got k = {k}", groups.len()),
        });
    }
    Ok((0..k)
        .map(|fold| {
            let (test, train): (Vec<_>, Vec<_>) = groups.iter().enumerate().partition(|(i, _)| i % k == fold);
            let pick = |v: Vec<(usize, &Vec<usize>)>| {
                let mut idx: Vec<usize> = v.into_iter().flat_map(|(_, g)| g.iter().copied()).collect();
                idx.sort_unstable();
                idx
            };
            Split {
                train: pick(train),
                test: pick(test),
            }
        })
        .collect())
}

/// `k` folds that hold out whole groups: `groups[i]` is sample `i`'s group (a session, a
/// station), the groups shuffled by `seed`; fold `i` holds out every `k`-th group.
pub fn grouped_kfold(groups: &[usize], k: usize, seed: u64) -> Result<Vec<Split>> {
    let mut ids: Vec<usize> = groups.to_vec();
    ids.sort_unstable();
    ids.dedup();
    if k < 2 || k > ids.len() {
        return Err(Error::InvalidArgument {
            what: "folds".into(),
            reason: format!(
                "grouped k-fold needs 2 ≤ k ≤ number of groups ({}), got k = {k}",
                ids.len()
            ),
        });
    }
    ids.shuffle(&mut StdRng::seed_from_u64(seed));
    Ok((0..k)
        .map(|fold| {
            let held: Vec<usize> = ids
                .iter()
                .enumerate()
                .filter(|(i, _)| i % k == fold)
                .map(|(_, g)| *g)
                .collect();
            let (test, train): (Vec<usize>, Vec<usize>) = (0..groups.len()).partition(|&i| held.contains(&groups[i]));
            Split { train, test }
        })
        .collect())
}

/// The samples at `indices`, cloned, in that order.
pub fn subset(samples: &[Sample], indices: &[usize]) -> Vec<Sample> {
    indices.iter().map(|&i| samples[i].clone()).collect()
}

/// What the folds of a cross-validation hold out together.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FoldBy {
    /// Whole poses (the markers measured at one configuration).
    Poses,
    /// Whole stations ([`Sample::station`]).
    Stations,
    /// Whole values of a named column: `groups[i]` is sample `i`'s.
    Column {
        /// The column's name, for reports.
        name: String,
        /// Sample `i`'s group.
        groups: Vec<usize>,
    },
}

impl FoldBy {
    /// By `column` when one is given, else by station when `samples` come from several,
    /// else by pose.
    pub fn choose(samples: &[Sample], column: Option<(String, Vec<usize>)>) -> FoldBy {
        match column {
            Some((name, groups)) => FoldBy::Column { name, groups },
            None if samples.iter().any(|s| s.station != samples[0].station) => FoldBy::Stations,
            None => FoldBy::Poses,
        }
    }
}

/// How to fold a cross-validation: `k` folds holding out what `by` says, shuffled by `seed`.
#[derive(Debug, Clone, PartialEq)]
pub struct FoldPlan {
    /// Number of folds.
    pub k: usize,
    /// Seed of the shuffle.
    pub seed: u64,
    /// What each fold holds out together.
    pub by: FoldBy,
}

/// How a cross-validation was folded, for reports: `folds: 5, grouped by station`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Folding {
    /// Number of folds.
    pub folds: usize,
    /// `pose`, `station` or the column's name.
    pub grouped_by: String,
}

impl std::fmt::Display for Folding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "folds: {}, grouped by {}", self.folds, self.grouped_by)
    }
}

/// `k` folds of `samples` holding out whole groups as `by` says, shuffled by `seed`. Grouped
/// by station or column, there are at most as many folds as groups (three stations give
/// three folds, each holding one out).
pub fn folds(samples: &[Sample], k: usize, seed: u64, by: &FoldBy) -> Result<(Vec<Split>, Folding)> {
    let grouped = |groups: &[usize], name: &str| -> Result<(Vec<Split>, Folding)> {
        if groups.len() != samples.len() {
            return Err(Error::Dimension {
                what: "fold groups".into(),
                expected: samples.len(),
                got: groups.len(),
            });
        }
        let mut ids = groups.to_vec();
        ids.sort_unstable();
        ids.dedup();
        let k = if k >= 2 { k.min(ids.len()) } else { k };
        let splits = grouped_kfold(groups, k, seed)?;
        // A group that holds nearly every row leaves its fold too little to fit: say so here,
        // not as a training set of one row deep inside a fit.
        if let Some(thin) = splits.iter().find(|s| s.train.len() < 2 && ids.len() > 1) {
            return Err(Error::InvalidArgument {
                what: format!("folds grouped by {name}"),
                reason: format!(
                    "a fold that holds out {} of the {} rows leaves {} to fit on: the groups are too uneven to \
                     cross-validate; group by a column of more, evener groups, or fold by pose",
                    thin.test.len(),
                    samples.len(),
                    thin.train.len()
                ),
            });
        }
        Ok((
            splits,
            Folding {
                folds: k,
                grouped_by: name.into(),
            },
        ))
    };
    match by {
        FoldBy::Poses => Ok((
            kfold(samples, k, seed)?,
            Folding {
                folds: k,
                grouped_by: "pose".into(),
            },
        )),
        FoldBy::Stations => {
            let stations: Vec<usize> = samples.iter().map(|s| s.station).collect();
            grouped(&stations, "station")
        }
        FoldBy::Column { name, groups } => grouped(groups, name),
    }
}
