//! Train/test splits and k-fold partitions of measurements, by pose.
//!
//! Samples that share a configuration (several markers measured at one pose) always stay on
//! the same side, so a held-out score never sees a pose that was trained on.

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;

use crate::error::{Error, Result};
use crate::measurement::Sample;

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
