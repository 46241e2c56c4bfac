//! Limits on the sizes a user can ask for (numbers of poses, pool sizes, draws, folds, rows,
//! columns). Each is derived from what one request may cost, in memory and in time, and checked
//! before any work starts: a few zeros too many are refused at once, with the largest size
//! that fits, instead of filling the memory or running for days.

use crate::error::{Error, Result};

/// The memory one request may fill (bytes): a quarter of a 16 GiB workstation's.
pub const MEMORY_BYTES: f64 = 4.0 * 1024.0 * 1024.0 * 1024.0;

/// The work one request may ask for (floating-point operations): about a quarter of an hour
/// at the billion a second one core sustains on this code's small, branchy loops.
pub const WORK_FLOPS: f64 = 1e12;

/// What one data row of a measurement file costs the work it goes into: calibration's
/// Jacobian holds three rows a measured position for each of up to a hundred parameters
/// (2.4 kB), and each of some fifty iterations forms its normal equations from them (3 · 100²
/// operations a row each time). Rows are counted and checked against this before any is read.
pub fn measurement_row_cost(rows: usize) -> Cost {
    Cost::per_unit(rows, 3.0 * 100.0 * 8.0, 50.0 * 3.0 * 100.0 * 100.0)
}

/// What a request of some size costs in total.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cost {
    /// Memory it fills (bytes).
    pub bytes: f64,
    /// Floating-point operations it does.
    pub flops: f64,
}

impl Cost {
    /// `n` units of `bytes` and `flops` each.
    pub fn per_unit(n: usize, bytes: f64, flops: f64) -> Cost {
        Cost {
            bytes: n as f64 * bytes,
            flops: n as f64 * flops,
        }
    }

    fn fits(&self) -> bool {
        self.bytes <= MEMORY_BYTES && self.flops <= WORK_FLOPS
    }
}

/// The largest size whose cost fits both limits, for a cost that grows with the size.
pub fn largest(cost: &dyn Fn(usize) -> Cost) -> usize {
    let (mut lo, mut hi) = (0usize, 1usize);
    while cost(hi).fits() {
        lo = hi;
        hi = match hi.checked_mul(2) {
            Some(h) => h,
            None => return usize::MAX,
        };
    }
    // cost(lo) fits (or lo is 0), cost(hi) does not.
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if cost(mid).fits() { lo = mid } else { hi = mid }
    }
    lo
}

/// Checks that a request of `asked` `unit`s (the size the user knows as `what`: `--n`,
/// `--pool`) costs no more than the limits; the error names the largest size that fits and
/// what the asked one would take.
pub fn check(what: &str, asked: usize, unit: &str, cost: &dyn Fn(usize) -> Cost) -> Result<()> {
    let c = cost(asked);
    if c.fits() {
        return Ok(());
    }
    Err(Error::TooLarge {
        what: what.into(),
        asked,
        unit: unit.into(),
        limit: largest(cost),
        reason: format!(
            "{asked} would take about {} of memory and {:.1e} floating-point operations (~{}); a request may take {} and {:.0e} (~{})",
            bytes(c.bytes),
            c.flops,
            duration(c.flops),
            bytes(MEMORY_BYTES),
            WORK_FLOPS,
            duration(WORK_FLOPS)
        ),
    })
}

/// `3.2 GiB`, `640 MiB`, ...
fn bytes(b: f64) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = b;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    format!("{v:.1} {}", UNITS[u])
}

/// The time `flops` take at a billion a second, in the largest unit that keeps it above one.
fn duration(flops: f64) -> String {
    let s = flops / 1e9;
    for (unit, len) in [("years", 3.15e7), ("days", 86400.0), ("h", 3600.0), ("min", 60.0)] {
        if s >= len {
            return format!("{:.0} {unit}", s / len);
        }
    }
    format!("{s:.0} s")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_size_is_the_last_that_fits_either_limit() {
        // 1 KiB each: memory allows 4 Mi units; 1e3 flops each: time allows 1e9.
        let memory_bound = |n| Cost::per_unit(n, 1024.0, 1e3);
        assert_eq!(largest(&memory_bound), 4 * 1024 * 1024);
        // Quadratic work: n² · 100 flops fit below 1e12 up to n = 1e5.
        let quadratic = |n: usize| Cost {
            bytes: 0.0,
            flops: (n as f64).powi(2) * 100.0,
        };
        assert_eq!(largest(&quadratic), 100_000);
        assert!(check("--n", 100_000, "poses", &quadratic).is_ok());
        let e = check("--n", 100_001, "poses", &quadratic).unwrap_err().to_string();
        assert!(e.starts_with("--n 100001: at most 100000 poses"), "{e}");
        // Free: any size fits.
        assert_eq!(largest(&|_| Cost::per_unit(1, 0.0, 0.0)), usize::MAX);
    }

    #[test]
    fn the_row_limit_is_set_by_the_time_of_a_calibration() {
        // 1.5e6 operations a row: 1e12 allow 666 666 rows; memory (2.4 kB a row) would allow
        // 1.8 million.
        assert_eq!(largest(&measurement_row_cost), 666_666);
    }

    #[test]
    fn sizes_and_times_read_in_their_units() {
        assert_eq!(bytes(4.0 * 1024.0 * 1024.0 * 1024.0), "4.0 GiB");
        assert_eq!(bytes(512.0), "512.0 B");
        assert_eq!(duration(1e12), "17 min");
        assert_eq!(duration(3.6e12), "1 h");
        assert_eq!(duration(5e9), "5 s");
    }
}
