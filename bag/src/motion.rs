//! Motion of the two streams: their speed on a common time grid, the clock offset that best
//! lines the two up, and the rests of the joints.

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

/// A signal sampled on the grid `k · step` (s from the import's time origin), known for the
/// grid points `start .. start + values.len()` (NaN where the stream had a gap).
#[derive(Debug, Clone, Default)]
pub struct GridSignal {
    start: i64,
    values: Vec<f64>,
    /// The last sample pushed: its time (s) and value.
    last: Option<(f64, f64)>,
}

/// Gaps between two samples longer than this (s) are not bridged on the grid.
pub const MAX_GAP: f64 = 0.25;

impl GridSignal {
    /// Adds the sample `v` at time `t` (s, after the previous sample's), linearly interpolated
    /// onto the grid points between the previous sample and this one; `max_points` bounds the
    /// signal's length (memory).
    pub fn push(&mut self, t: f64, v: f64, step: f64, max_points: usize) -> Result<(), String> {
        if let Some((t0, v0)) = self.last
            && t - t0 <= MAX_GAP
        {
            let first = (t0 / step).floor() as i64 + 1;
            let last = (t / step).floor() as i64;
            if self.values.is_empty() {
                self.start = first;
            }
            for k in first..=last {
                let i = usize::try_from(k - self.start)
                    .map_err(|_| "a time stamp before the stream's first".to_string())?;
                if i >= max_points {
                    return Err(format!(
                        "the streams span more than {:.0} s, the longest recording imported at once",
                        max_points as f64 * step
                    ));
                }
                if i >= self.values.len() {
                    self.values.resize(i + 1, f64::NAN);
                }
                let s = k as f64 * step;
                self.values[i] = v0 + (v - v0) * (s - t0) / (t - t0);
            }
        }
        self.last = Some((t, v));
        Ok(())
    }

    /// The known values, without gaps.
    fn finite(&self) -> impl Iterator<Item = f64> + '_ {
        self.values.iter().copied().filter(|v| v.is_finite())
    }

    /// The signal centred and scaled to unit variance, gaps as 0, and its mask (1 where known).
    fn standardized(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        let n = self.finite().count();
        if n < 3 {
            return None;
        }
        let mean = self.finite().sum::<f64>() / n as f64;
        let var = self.finite().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
        if var <= 0.0 || !var.is_finite() {
            return None;
        }
        let sd = var.sqrt();
        let z = self
            .values
            .iter()
            .map(|v| if v.is_finite() { (v - mean) / sd } else { 0.0 })
            .collect();
        let mask = self.values.iter().map(|v| f64::from(u8::from(v.is_finite()))).collect();
        Some((z, mask))
    }
}

/// The estimated clock offset: the tracker's clock minus the joints' at the same instant.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ClockOffset {
    /// Seconds: an event the joints stamp `t` the tracker stamps `t + seconds`.
    pub seconds: f64,
    /// Its standard uncertainty (s): the spread of the offsets of separate blocks of the
    /// recording over the root of their number, or one grid step when fewer than three blocks
    /// move.
    pub std: f64,
    /// How many blocks of the recording gave an offset of their own.
    pub blocks: usize,
    /// The peak's normalized cross-correlation (1: the speeds match perfectly).
    pub correlation: f64,
}

/// Blocks the recording is cut into for the offset's uncertainty.
const BLOCKS: usize = 8;
/// Half the window (grid steps) in which each block's own peak is sought, around the whole
/// recording's.
const BLOCK_WINDOW: i64 = 50;

/// The lag (s) by which `tracker` trails `joints` (the same speed from the joints' stream),
/// from the peak of the normalized
/// cross-correlation of the two speed signals (computed for every lag at once by FFT, each
/// lag's sum divided by its number of overlapping grid points, lags whose overlap is less than
/// half the shorter signal left out), refined between grid points by the parabola through the
/// peak and its neighbours.
pub fn estimate_offset(joints: &GridSignal, tracker: &GridSignal, step: f64) -> Result<ClockOffset, String> {
    let (a, ma) = joints
        .standardized()
        .ok_or("the joints do not move: a clock offset is estimated from motion")?;
    let (b, mb) = tracker
        .standardized()
        .ok_or("the tracked point does not move: a clock offset is estimated from motion")?;
    let (la, lb) = (a.len(), b.len());
    let n = (la + lb).next_power_of_two();
    let corr = correlate(&a, &b, n);
    let count = correlate(&ma, &mb, n);
    let min_overlap = 0.5 * (ma.iter().sum::<f64>()).min(mb.iter().sum::<f64>());
    // Array lag m (B's index minus A's) → its circular index.
    let at = |v: &[f64], m: i64| v[m.rem_euclid(n as i64) as usize];
    let normalized = |m: i64| {
        let c = at(&count, m);
        (c >= min_overlap && c > 0.5).then(|| at(&corr, m) / c)
    };
    let lags = -(la as i64 - 1)..=(lb as i64 - 1);
    let (best, peak) = lags
        .filter_map(|m| normalized(m).map(|c| (m, c)))
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .ok_or("the two streams overlap too little in time to be lined up")?;
    let shift = tracker.start - joints.start;
    let refined = best as f64 + parabola_vertex(normalized(best - 1), peak, normalized(best + 1));
    let seconds = (refined + shift as f64) * step;
    // Each block's own peak near the whole recording's.
    let mut offsets = Vec::new();
    for k in 0..BLOCKS {
        let (lo, hi) = (k * la / BLOCKS, (k + 1) * la / BLOCKS);
        let local = |m: i64| -> Option<f64> {
            let (mut sum, mut cnt) = (0.0, 0.0);
            for i in lo..hi {
                let j = i as i64 + m;
                if j >= 0 && (j as usize) < lb {
                    sum += a[i] * b[j as usize];
                    cnt += ma[i] * mb[j as usize];
                }
            }
            (cnt > 0.5 * (hi - lo) as f64).then(|| sum / cnt)
        };
        // A block where the joints hardly move has no peak of its own.
        let moving = (lo..hi).filter(|&i| ma[i] > 0.0 && a[i] > 0.0).count();
        if moving < (hi - lo) / 10 {
            continue;
        }
        let window: Vec<(i64, f64)> = (best - BLOCK_WINDOW..=best + BLOCK_WINDOW)
            .filter_map(|m| local(m).map(|c| (m, c)))
            .collect();
        let Some(&(m, c)) = window.iter().max_by(|x, y| x.1.total_cmp(&y.1)) else {
            continue;
        };
        if (m - best).abs() == BLOCK_WINDOW {
            continue;
        }
        offsets.push((m as f64 + parabola_vertex(local(m - 1), c, local(m + 1)) + shift as f64) * step);
    }
    let std = if offsets.len() >= 3 {
        let mean = offsets.iter().sum::<f64>() / offsets.len() as f64;
        let var = offsets.iter().map(|o| (o - mean).powi(2)).sum::<f64>() / (offsets.len() - 1) as f64;
        (var / offsets.len() as f64).sqrt()
    } else {
        step
    };
    Ok(ClockOffset {
        seconds,
        std,
        blocks: offsets.len(),
        correlation: peak,
    })
}

/// `r[m] = Σ_i a[i] · b[i + m]` for every lag, at circular index `m mod n` (`n ≥ len a + len b`).
fn correlate(a: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    let padded = |v: &[f64]| {
        let mut out = vec![Complex::new(0.0, 0.0); n];
        out.iter_mut().zip(v).for_each(|(o, x)| o.re = *x);
        out
    };
    let (mut fa, mut fb) = (padded(a), padded(b));
    forward.process(&mut fa);
    forward.process(&mut fb);
    let mut prod: Vec<Complex<f64>> = fa.iter().zip(&fb).map(|(x, y)| x.conj() * y).collect();
    inverse.process(&mut prod);
    prod.iter().map(|c| c.re / n as f64).collect()
}

/// Where, between -1 and 1 grid steps from the middle sample, the parabola through three
/// samples peaks; 0 without both neighbours or when they do not bracket a peak.
fn parabola_vertex(left: Option<f64>, mid: f64, right: Option<f64>) -> f64 {
    match (left, right) {
        (Some(l), Some(r)) => {
            let curvature = l - 2.0 * mid + r;
            if curvature < 0.0 {
                (0.5 * (l - r) / curvature).clamp(-1.0, 1.0)
            } else {
                0.0
            }
        }
        _ => 0.0,
    }
}

/// A rest of the joints: its first and last joint samples' times (s) and the mean
/// configuration over it.
#[derive(Debug, Clone, PartialEq)]
pub struct Rest {
    pub start: f64,
    pub end: f64,
    pub q: Vec<f64>,
    pub samples: u64,
}

/// Finds, sample by sample, the runs of joint samples over which no coordinate moves faster
/// than its threshold (from the differences of consecutive positions) for at least the rest
/// time, and counts the samples that are in none.
#[derive(Debug, Clone)]
pub struct RestDetector {
    thresholds: Vec<f64>,
    min_duration: f64,
    previous: Option<(f64, Vec<f64>)>,
    /// The previous sample is in the current run.
    previous_in_run: bool,
    run: Option<Rest>,
    pub rests: Vec<Rest>,
    /// Joint samples taken while the joints moved.
    pub moving: u64,
    /// Joint samples of runs shorter than the rest time.
    pub too_short: u64,
}

impl RestDetector {
    /// Thresholds per coordinate (rad/s, m/s for a prismatic one) and the rest time (s).
    pub fn new(thresholds: Vec<f64>, min_duration: f64) -> Self {
        RestDetector {
            thresholds,
            min_duration,
            previous: None,
            previous_in_run: false,
            run: None,
            rests: Vec::new(),
            moving: 0,
            too_short: 0,
        }
    }

    /// The next joint sample (time after the previous one's).
    pub fn push(&mut self, t: f64, q: &[f64]) {
        if let Some((t0, q0)) = &self.previous {
            let dt = t - t0;
            let still = dt <= MAX_GAP
                && q.iter()
                    .zip(q0)
                    .zip(&self.thresholds)
                    .all(|((a, b), thr)| (a - b).abs() <= thr * dt);
            if still {
                let run = self.run.get_or_insert_with(|| Rest {
                    start: *t0,
                    end: *t0,
                    q: q0.clone(),
                    samples: 1,
                });
                run.end = t;
                run.samples += 1;
                run.q.iter_mut().zip(q).for_each(|(s, v)| *s += v);
            } else {
                if !self.previous_in_run {
                    self.moving += 1;
                }
                self.close_run();
            }
            self.previous_in_run = still;
        }
        match &mut self.previous {
            Some((t0, q0)) => {
                *t0 = t;
                q0.copy_from_slice(q);
            }
            None => self.previous = Some((t, q.to_vec())),
        }
    }

    fn close_run(&mut self) {
        if let Some(mut run) = self.run.take() {
            if run.end - run.start >= self.min_duration {
                run.q.iter_mut().for_each(|s| *s /= run.samples as f64);
                self.rests.push(run);
            } else {
                self.too_short += run.samples;
            }
        }
    }

    /// Ends the stream: the last run is closed.
    pub fn finish(&mut self) {
        if self.previous.is_some() && !self.previous_in_run {
            self.moving += 1;
        }
        self.close_run();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A speed profile of moves every 3.7 s whose lengths and heights follow the golden
    /// ratio's multiples: no shift but zero lines it up with itself.
    fn profile(t: f64) -> f64 {
        let k = (t / 3.7).floor();
        let phase = t - 3.7 * k;
        let len = 0.5 + 0.8 * (k * 0.618_034).fract();
        let height = 0.5 + (k * 0.381_966).fract();
        if phase < len {
            height * (std::f64::consts::PI * phase / len).sin().powi(2)
        } else {
            0.0
        }
    }

    #[test]
    fn the_offset_of_two_sampled_speeds_is_found_between_grid_points() {
        let step = 0.01;
        for (offset, joint_rate, tracker_rate) in [(0.1234, 100.0, 50.0), (-2.0371, 250.0, 120.0), (0.0, 100.0, 100.0)]
        {
            let (mut a, mut b) = (GridSignal::default(), GridSignal::default());
            let n = (60.0 * joint_rate) as usize;
            for i in 0..n {
                let t = 5.0 + i as f64 / joint_rate;
                a.push(t, profile(t), step, 1 << 20).unwrap();
            }
            // The tracker stamps an event at joint time t as t + offset, its speed in other units.
            for i in 0..(60.0 * tracker_rate) as usize {
                let t = 5.0 + i as f64 / tracker_rate;
                b.push(t + offset, 0.3 * profile(t) + 0.01, step, 1 << 20).unwrap();
            }
            let est = estimate_offset(&a, &b, step).unwrap();
            assert!(
                (est.seconds - offset).abs() < 1e-3,
                "offset {offset}: estimated {} ± {}",
                est.seconds,
                est.std
            );
            assert!(est.blocks >= 3 && est.correlation > 0.9, "{est:?}");
        }
    }

    #[test]
    fn still_streams_have_no_offset() {
        let (mut a, mut b) = (GridSignal::default(), GridSignal::default());
        for i in 0..500 {
            a.push(i as f64 * 0.01, 0.0, 0.01, 1 << 20).unwrap();
            b.push(i as f64 * 0.01, (i as f64).sin(), 0.01, 1 << 20).unwrap();
        }
        assert!(
            estimate_offset(&a, &b, 0.01)
                .unwrap_err()
                .contains("joints do not move")
        );
    }

    #[test]
    fn a_signal_longer_than_its_bound_is_refused() {
        let mut a = GridSignal::default();
        let err = (0..2000).try_for_each(|i| a.push(i as f64 * 0.01, 1.0, 0.01, 1000));
        assert!(err.unwrap_err().contains("span more than 10 s"));
    }

    #[test]
    fn rests_are_the_still_runs_at_least_the_rest_time_long() {
        // 100 Hz: still for 1 s at 0, a move of 0.5 s, still 0.3 s (too short), a move, still 2 s.
        let mut det = RestDetector::new(vec![0.01], 0.5);
        let mut t = 0.0;
        let mut push = |det: &mut RestDetector, n: usize, q: &dyn Fn(usize) -> f64| {
            for i in 0..n {
                det.push(t, &[q(i)]);
                t += 0.01;
            }
        };
        push(&mut det, 101, &|_| 0.0);
        push(&mut det, 50, &|i| 0.02 * (i + 1) as f64);
        push(&mut det, 31, &|_| 1.0);
        push(&mut det, 50, &|i| 1.0 + 0.02 * (i + 1) as f64);
        push(&mut det, 201, &|_| 2.0);
        det.finish();
        assert_eq!(det.rests.len(), 2);
        assert_eq!((det.rests[0].samples, det.rests[0].q[0]), (101, 0.0));
        assert!((det.rests[0].end - det.rests[0].start - 1.0).abs() < 1e-9);
        // The last sample of each move reaches the rest's position and is the rest's first.
        assert_eq!((det.rests[1].samples, det.rests[1].q[0]), (202, 2.0));
        assert_eq!(det.too_short, 32);
        assert_eq!(det.moving, 49 + 49);
        assert_eq!(det.moving + det.too_short + 101 + 202, 101 + 50 + 31 + 50 + 201);
    }
}
