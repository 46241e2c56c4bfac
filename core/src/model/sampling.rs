//! Point sets in the unit cube and joint configurations inside the limits.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::error::{Error, Result};
use crate::model::tree::KinematicTree;

/// How to spread points over the joint space.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampler {
    /// Owen-scrambled Sobol sequence (quasi-random; the seed picks the scrambling).
    Sobol,
    /// Halton sequence, one prime base per dimension (quasi-random; the seed is not used).
    Halton,
    /// Pseudo-random uniform points (seeded).
    Random,
    /// A full-factorial grid, thinned evenly to the requested count.
    Grid,
}

impl Sampler {
    /// Parses `sobol`, `halton`, `random` or `grid`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "sobol" => Ok(Sampler::Sobol),
            "halton" => Ok(Sampler::Halton),
            "random" => Ok(Sampler::Random),
            "grid" => Ok(Sampler::Grid),
            other => Err(Error::InvalidArgument {
                what: "sampler".into(),
                reason: format!("unknown sampler `{other}`; expected sobol, halton, random or grid"),
            }),
        }
    }
}

const PRIMES: [u8; 24] = [
    2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89,
];

/// Coordinate `d` of point `i` of the scrambled Sobol sequence of `seed`, in `[0, 1)`. The
/// sequence's table has 256 dimensions; further ones repeat it under other scrambles, so any
/// number of joints gets well-spread values. Allocation-free (IK restarts call it per joint).
pub fn sobol_coordinate(i: u32, d: usize, seed: u32) -> f64 {
    const TABLE: usize = sobol_burley::NUM_DIMENSIONS as usize;
    f64::from(sobol_burley::sample(i, (d % TABLE) as u32, seed ^ (d / TABLE) as u32))
}

/// The most points the Sobol sampler draws: its table's length, 2^16; beyond, the sequence
/// gives unspecified numbers.
pub const SOBOL_POINTS: usize = 1 << 16;

/// `n` points in `[0, 1)^dim`.
pub fn unit_points(sampler: Sampler, n: usize, dim: usize, seed: u64) -> Result<Vec<Vec<f64>>> {
    match sampler {
        Sampler::Sobol if n > SOBOL_POINTS => Err(Error::TooLarge {
            what: "sobol sampler".into(),
            asked: n,
            unit: "points".into(),
            limit: SOBOL_POINTS,
            reason: "the length of its table; draw more with halton or random".into(),
        }),
        Sampler::Sobol => {
            let seed = (seed ^ (seed >> 32)) as u32;
            Ok((0..n as u32)
                .map(|i| (0..dim).map(|d| sobol_coordinate(i, d, seed)).collect())
                .collect())
        }
        Sampler::Halton => {
            if dim > PRIMES.len() {
                return Err(Error::InvalidArgument {
                    what: "dimensions".into(),
                    reason: format!("the Halton sampler supports up to {}, not {dim}", PRIMES.len()),
                });
            }
            // Index 0 is the origin in every base; start at 1.
            Ok((1..=n)
                .map(|i| PRIMES[..dim].iter().map(|b| halton::number(*b, i)).collect())
                .collect())
        }
        Sampler::Random => {
            let mut rng = StdRng::seed_from_u64(seed);
            Ok((0..n)
                .map(|_| (0..dim).map(|_| rng.random::<f64>()).collect())
                .collect())
        }
        Sampler::Grid => {
            if n == 0 || dim == 0 {
                return Ok(vec![Vec::new(); n]);
            }
            let levels = (1..)
                .find(|k: &usize| k.checked_pow(dim as u32).is_none_or(|t| t >= n))
                .unwrap_or(2)
                .max(2);
            let total = levels.checked_pow(dim as u32).ok_or_else(|| Error::InvalidArgument {
                what: "grid".into(),
                reason: format!("{levels} levels in {dim} dimensions overflow the point count"),
            })?;
            Ok((0..n)
                .map(|i| {
                    let mut idx = i * total / n;
                    (0..dim)
                        .map(|_| {
                            let l = idx % levels;
                            idx /= levels;
                            l as f64 / (levels - 1) as f64
                        })
                        .collect()
                })
                .collect())
        }
    }
}

/// `n` joint configurations inside the limits of `tree` (unlimited revolute joints span ±π,
/// unlimited prismatic ones are an error).
pub fn configurations(tree: &KinematicTree, sampler: Sampler, n: usize, seed: u64) -> Result<Vec<Vec<f64>>> {
    let mut ranges = Vec::new();
    for (i, l) in tree.coordinate_limits().iter().enumerate() {
        ranges.push(match (l, tree.coordinate_is_prismatic()[i]) {
            (Some(l), _) => (l.lower, l.upper),
            (None, false) => (-std::f64::consts::PI, std::f64::consts::PI),
            (None, true) => {
                return Err(Error::InvalidArgument {
                    what: format!("prismatic joint `{}`", tree.coordinate_names()[i]),
                    reason: "has no limits; sampling needs a range".into(),
                });
            }
        });
    }
    Ok(unit_points(sampler, n, ranges.len(), seed)?
        .into_iter()
        .map(|u| u.iter().zip(&ranges).map(|(u, (lo, hi))| lo + u * (hi - lo)).collect())
        .collect())
}
