//! A demo's protocol repeated over consecutive seeds: how each row spreads, and on how many
//! seeds each of the demo's claims held. One seed is one draw of training poses, targets, noise
//! and network initialisation; a claim about a method is only as good as the share of draws it
//! survives.

use std::fmt;

use serde::Serialize;

use super::{PaperValue, Table};

/// One row's mean |z| error over the seeds (mm).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RowSpread {
    /// The pipeline.
    pub name: String,
    /// The paper's value for it, when it has one.
    pub paper: Option<PaperValue>,
    /// Mean over the seeds.
    pub mean_mm: f64,
    /// Median over the seeds.
    pub median_mm: f64,
    /// Smallest over the seeds.
    pub min_mm: f64,
    /// Largest over the seeds.
    pub max_mm: f64,
}

/// On how many seeds a claim held.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClaimCount {
    /// The claim.
    pub claim: String,
    /// Seeds it held on.
    pub held: usize,
    /// Seeds run.
    pub of: usize,
}

/// A protocol run over several seeds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeedSweep {
    /// Title of the protocol's table.
    pub title: String,
    /// The seeds, in the order run.
    pub seeds: Vec<u64>,
    /// Mean |z| of the measurement noise alone (mm).
    pub noise_mean_abs_z_mm: f64,
    /// Every row of the table, spread over the seeds.
    pub rows: Vec<RowSpread>,
    /// The claims checked on each seed's table.
    pub claims: Vec<ClaimCount>,
    /// Each seed's table.
    pub tables: Vec<Table>,
}

impl SeedSweep {
    /// Summarises `tables` (one per seed in `seeds`, all with the same rows); `claims` gives
    /// each claim's verdict on one table.
    ///
    /// # Panics
    /// When `tables` is empty ([`rock_drill::sweep`](super::rock_drill::sweep) refuses zero
    /// seeds before running any).
    pub fn new(seeds: Vec<u64>, tables: Vec<Table>, claims: impl Fn(&Table) -> Vec<(String, bool)>) -> Self {
        let first = &tables[0];
        let rows = first
            .rows
            .iter()
            .enumerate()
            .map(|(i, row)| {
                let mut values: Vec<f64> = tables.iter().map(|t| t.rows[i].mean_abs_z_mm).collect();
                values.sort_by(f64::total_cmp);
                let n = values.len();
                let median = if n % 2 == 1 {
                    values[n / 2]
                } else {
                    0.5 * (values[n / 2 - 1] + values[n / 2])
                };
                RowSpread {
                    name: row.name.clone(),
                    paper: row.paper,
                    mean_mm: values.iter().sum::<f64>() / n as f64,
                    median_mm: median,
                    min_mm: values[0],
                    max_mm: values[n - 1],
                }
            })
            .collect();
        let mut counts: Vec<ClaimCount> = Vec::new();
        for t in &tables {
            for (k, (claim, held)) in claims(t).into_iter().enumerate() {
                if counts.len() == k {
                    counts.push(ClaimCount { claim, held: 0, of: 0 });
                }
                counts[k].held += usize::from(held);
                counts[k].of += 1;
            }
        }
        SeedSweep {
            title: first.title.clone(),
            seeds,
            noise_mean_abs_z_mm: first.noise_mean_abs_z_mm,
            rows,
            claims: counts,
            tables,
        }
    }
}

/// The spread of every row and the claims' counts as text.
impl fmt::Display for SeedSweep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let seeds = match (self.seeds.first(), self.seeds.last()) {
            (Some(a), Some(b)) => format!("seeds {a} to {b}"),
            _ => "no seeds".into(),
        };
        writeln!(f, "== {} over {} ({} runs)", self.title, seeds, self.seeds.len())?;
        writeln!(
            f,
            "   mean |z| error in mm over the seeds (mean |z| of the noise alone {:.3} mm)",
            self.noise_mean_abs_z_mm
        )?;
        writeln!(
            f,
            "   {:<50} {:>9} {:>9} {:>9} {:>9} {:>8}",
            "pipeline", "mean", "median", "min", "max", "paper"
        )?;
        for r in &self.rows {
            let paper = r.paper.map_or(String::new(), |p| format!("{:.2}", p.mean_mm));
            writeln!(
                f,
                "   {:<50} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>8}",
                r.name, r.mean_mm, r.median_mm, r.min_mm, r.max_mm, paper
            )?;
        }
        writeln!(f, "   claims, seeds on which each held:")?;
        for c in &self.claims {
            writeln!(f, "   {:>3}/{:<3} {}", c.held, c.of, c.claim)?;
        }
        Ok(())
    }
}
