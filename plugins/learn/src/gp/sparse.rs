//! The inducing-point (subset-of-regressors) mean of a large training set: every row's target
//! enters the weights, through `m` inducing rows, in O(n m²) time and O(m²) memory.
//!
//! With `K_mm` the kernel among the inducing rows and `K_nm` between all rows and them, the
//! mean is `k_*m α` with `α = (σ_n² K_mm + K_mn K_nm)⁻¹ K_mn y` (Quiñonero-Candela &
//! Rasmussen 2005, eq. 16b). `K_mn K_nm` and `K_mn y` are summed over blocks of rows, so the
//! n × m matrix never exists whole.

use armcomp_core::{Error, Result};
use nalgebra::DMatrix;

use crate::rbf::kernel_row;

use super::GpHyperParams;

/// Rows of `K_nm` formed at a time: enough for the matrix product to run at speed, few enough
/// that the block (`BLOCK × m` values) stays small beside `K_mm`.
const BLOCK: usize = 512;

/// Bytes the sparse fit holds at its peak for `m` inducing rows and `outputs` outputs:
/// `σ_n² K_mm + K_mn K_nm`, its factor, the block of `K_nm` and its transpose.
pub(super) fn sparse_bytes(m: usize, outputs: usize) -> u64 {
    let values = 2 * m * m + 2 * BLOCK * m + 2 * m * outputs;
    8 * values as u64
}

/// The weights α (row-major `m × g`) of the inducing rows `inducing` (length-scaled, `m × d`)
/// for the length-scaled rows `scaled` (`n × d`) and their standardised targets `targets`
/// (row-major `n × g`). A diagonal jitter (a fraction of the matrix's mean diagonal, grown
/// until the factorisation succeeds) is added only when it fails.
pub(super) fn sparse_weights(
    scaled: &[f64],
    inducing: &[f64],
    d: usize,
    hyper: &GpHyperParams,
    targets: &[f64],
) -> Result<Vec<f64>> {
    let n = scaled.len() / d;
    let m = inducing.len() / d;
    let g = targets.len() / n;
    let sf2 = hyper.signal_std * hyper.signal_std;
    let columns = super::transpose(inducing, d);
    let mut a = super::signal_matrix(inducing, d, hyper.signal_std) * (hyper.noise_std * hyper.noise_std);
    let mut b = DMatrix::<f64>::zeros(m, g);
    let mut row = vec![0.0; m];
    for first in (0..n).step_by(BLOCK) {
        let rows = BLOCK.min(n - first);
        // K_mn for this block: column i is row first + i's kernel against the inducing rows.
        let mut k_mc = DMatrix::<f64>::zeros(m, rows);
        let mut y_c = DMatrix::<f64>::zeros(rows, g);
        for i in 0..rows {
            let r = first + i;
            kernel_row(&columns, &scaled[r * d..(r + 1) * d], sf2, &mut row);
            k_mc.column_mut(i).copy_from_slice(&row);
            for c in 0..g {
                y_c[(i, c)] = targets[r * g + c];
            }
        }
        a.gemm(1.0, &k_mc, &k_mc.transpose(), 1.0);
        b.gemm(1.0, &k_mc, &y_c, 1.0);
    }
    let mean_diagonal = a.diagonal().mean();
    let chol = std::iter::once(0.0)
        .chain((0..10).map(|e| mean_diagonal * 1e-12 * 10f64.powi(e)))
        .find_map(|j| {
            let mut aj = a.clone();
            for i in 0..m {
                aj[(i, i)] += j;
            }
            aj.cholesky()
        })
        .ok_or_else(|| Error::Degenerate {
            what: "gp (inducing rows)".into(),
            reason: "the inducing rows' normal matrix is not positive definite even with jitter".into(),
        })?;
    chol.solve_mut(&mut b);
    Ok((0..m)
        .flat_map(|i| (0..g).map(move |c| (i, c)))
        .map(|(i, c)| b[(i, c)])
        .collect())
}
