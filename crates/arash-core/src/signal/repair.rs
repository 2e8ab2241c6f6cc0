//! Logs as real controllers write them, repaired on request: a corrupt block at either end
//! trimmed, and time stamps that are not one uniform stream resampled onto one.
//!
//! Identification and the diagnosis need one uniform stream ([`super::preprocess::validate_log`]
//! refuses anything else, naming the sample). Real logs often are not: a controller's log may
//! start with a stale sample stamped 2 ms after the previous one, or with a block written before
//! the clock was set, and a loop that overruns stamps each sample when it was really taken. The
//! repair is opt-in (`repair=True` in Python, `--repair` on the command line) because it changes
//! the data: what it did is reported, row by row, with the reasons of the fit.
//!
//! Two readings of uneven stamps are told apart by the stamps themselves. A fixed-rate stream
//! stamped by its host (the KUKA LWR4+ logs of `../shared/data`) has stamps that scatter around
//! one uniform line by less than half a step: its samples are uniform and its stamps are noise,
//! so nothing is resampled. Stamps that leave that line by half a step or more (a missed or an
//! early sample, a loop that drifts) are the samples' own times, and the log is resampled at them.

pub use crate::signal::resample::resample;

use crate::choices::{Choice, LogEnd, RunBreak};

/// A step of up to this many median steps is filled by interpolation (two samples missed); a
/// longer one is a gap, across which the log is not one run.
pub const MAX_FILLED_STEPS: f64 = 3.0;

/// At most this share of a log's rows may be trimmed from its ends: more, and which block is the
/// run is no longer clear, so the repair refuses and names the break.
pub const MAX_TRIMMED_SHARE: f64 = 0.25;

/// Stamps within this share of a step of one uniform line are a uniform stream's, stamped with
/// noise (the strict check accepts jitter below the same half step).
pub const STAMP_NOISE_STEPS: f64 = 0.5;

/// A repair that cannot be made, naming the input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RepairError {
    #[error("{name} has {got} values, expected {expected} ({samples} samples × {width})")]
    Shape { name: String, got: usize, expected: usize, samples: usize, width: usize },
    #[error("the log has no run of at least two usable rows (finite, with increasing t) to repair")]
    NothingUsable,
    #[error(
        "the longest usable run is rows {first}–{last}, and trimming the rest would drop {share:.0} % of the log, more \
         than {max:.0} %: {why}. Only a block at either end is trimmed; split the log there"
    )]
    TooMuchTrimmed { first: usize, last: usize, share: f64, max: f64, why: String },
}

/// The repaired log: `t` and each signal (row-major, widths as given), and what was done.
#[derive(Clone, Debug, PartialEq)]
pub struct Repaired {
    pub t: Vec<f64>,
    pub signals: Vec<Vec<f64>>,
    /// One choice per change, for the reasons; empty when the log needed nothing.
    pub report: Vec<Choice>,
}

/// A signal to repair alongside `t`: its name (for errors), values (row-major) and width.
pub type Signal<'a> = (&'a str, &'a [f64], usize);

/// Repair a log: keep the longest run of rows that are finite in `t` and every signal, with `t`
/// increasing by at most [`MAX_FILLED_STEPS`] median steps, trimming what lies before and after
/// it (at most [`MAX_TRIMMED_SHARE`] of the rows); then, unless its stamps are one uniform
/// stream's within [`STAMP_NOISE_STEPS`], resample every signal at the median step by linear
/// interpolation. A log that needs neither comes back unchanged with an empty report.
pub fn repair(t: &[f64], signals: &[Signal]) -> Result<Repaired, RepairError> {
    let n = t.len();
    for &(name, values, width) in signals {
        if values.len() != n * width {
            let name = name.to_string();
            return Err(RepairError::Shape { name, got: values.len(), expected: n * width, samples: n, width });
        }
    }
    let unusable = |i: usize| -> Option<&str> {
        if !t[i].is_finite() {
            return Some("t");
        }
        signals.iter().find(|(_, v, w)| v[i * w..(i + 1) * w].iter().any(|x| !x.is_finite())).map(|s| s.0)
    };
    let median = median_step(t, &unusable).ok_or(RepairError::NothingUsable)?;
    // Where a run ends before row i: an unusable row, or a step back, or a gap.
    let breaks_before =
        |i: usize| unusable(i).is_some() || unusable(i - 1).is_some() || !fills(t[i] - t[i - 1], median);
    let (first, end) = longest_run(n, &unusable, &breaks_before).ok_or(RepairError::NothingUsable)?;
    let mut report = Vec::new();
    let why_at = |i: usize| describe_break(t, i, median, &unusable);
    if first > 0 {
        report.push(Choice::Trimmed {
            log: String::new(),
            end: LogEnd::Start,
            first: 0,
            last: first - 1,
            why: why_at(first),
        });
    }
    if end < n {
        report.push(Choice::Trimmed {
            log: String::new(),
            end: LogEnd::End,
            first: end,
            last: n - 1,
            why: why_at(end),
        });
    }
    let share = (n - (end - first)) as f64 / n as f64;
    if share > MAX_TRIMMED_SHARE {
        let why = report.iter().map(Choice::to_string).collect::<Vec<_>>().join("; ");
        return Err(RepairError::TooMuchTrimmed {
            first,
            last: end - 1,
            share: 100.0 * share,
            max: 100.0 * MAX_TRIMMED_SHARE,
            why,
        });
    }
    let run_t = &t[first..end];
    let run: Vec<Vec<f64>> = signals.iter().map(|(_, v, w)| v[first * w..end * w].to_vec()).collect();
    let off = stamps_off_line(run_t);
    if off < STAMP_NOISE_STEPS {
        return Ok(Repaired { t: run_t.to_vec(), signals: run, report });
    }
    let (t0, last) = (run_t[0], run_t[run_t.len() - 1]);
    let count = ((last - t0) / median).round() as usize + 1;
    let grid: Vec<f64> = (0..count).map(|i| t0 + i as f64 * median).collect();
    let widths: Vec<usize> = signals.iter().map(|s| s.2).collect();
    let (resampled, blended) = resample(run_t, &run, &widths, &grid);
    let (shortest, longest) =
        run_t.windows(2).map(|w| w[1] - w[0]).fold((f64::INFINITY, 0.0f64), |(a, b), s| (a.min(s), b.max(s)));
    report.push(Choice::Resampled {
        log: String::new(),
        first,
        last: end - 1,
        rate_hz: 1.0 / median,
        samples: count,
        blended,
        off_steps: off,
        shortest_s: shortest,
        longest_s: longest,
        median_s: median,
    });
    Ok(Repaired { t: grid, signals: resampled, report })
}

/// Whether a step is one the run holds: forward, and at most [`MAX_FILLED_STEPS`] median steps.
fn fills(step: f64, median: f64) -> bool {
    step > 0.0 && step <= MAX_FILLED_STEPS * median
}

/// The median of the forward steps between usable neighbouring rows.
fn median_step<'a>(t: &[f64], unusable: &dyn Fn(usize) -> Option<&'a str>) -> Option<f64> {
    let mut steps: Vec<f64> = (1..t.len())
        .filter(|&i| unusable(i).is_none() && unusable(i - 1).is_none())
        .map(|i| t[i] - t[i - 1])
        .filter(|s| *s > 0.0)
        .collect();
    if steps.is_empty() {
        return None;
    }
    let middle = steps.len() / 2;
    Some(*steps.select_nth_unstable_by(middle, f64::total_cmp).1)
}

/// The longest run of usable rows with no break inside, as `(first, end)` (end exclusive), of at
/// least two rows.
fn longest_run<'a>(
    n: usize,
    unusable: &dyn Fn(usize) -> Option<&'a str>,
    breaks_before: &dyn Fn(usize) -> bool,
) -> Option<(usize, usize)> {
    let mut best: Option<(usize, usize)> = None;
    let mut start = 0;
    for i in 1..=n {
        if i == n || breaks_before(i) {
            let usable = unusable(start).is_none();
            if usable && i - start >= 2 && best.is_none_or(|(a, b)| i - start > b - a) {
                best = Some((start, i));
            }
            start = i;
        }
    }
    best
}

/// Why the run starts or stops at row `i` (the first row after the trimmed block, or the first
/// row trimmed): the unusable row, the step back, or the gap.
fn describe_break<'a>(t: &[f64], i: usize, median: f64, unusable: &dyn Fn(usize) -> Option<&'a str>) -> RunBreak {
    let bad = [i - 1, i].into_iter().find_map(|r| unusable(r).map(|name| (r, name)));
    match bad {
        Some((row, name)) => RunBreak::NotFinite { row, signal: name.to_string() },
        None if t[i] <= t[i - 1] => RunBreak::TimeGoesBack { row: i, from_s: t[i - 1], to_s: t[i] },
        None => RunBreak::Gap {
            row: i,
            steps: (t[i] - t[i - 1]) / median,
            seconds: t[i] - t[i - 1],
            max_steps: MAX_FILLED_STEPS,
        },
    }
}

/// The least-squares line through the stamps `t` against their index: `(step, mean index, mean
/// time)`. Jitter, even at the ends, does not bias its step.
pub fn stamp_line(t: &[f64]) -> (f64, f64, f64) {
    let n = t.len();
    let (mean_i, mean_t) = ((n - 1) as f64 / 2.0, t.iter().sum::<f64>() / n as f64);
    let (mut num, mut den) = (0.0, 0.0);
    for (i, ti) in t.iter().enumerate() {
        num += (i as f64 - mean_i) * (ti - mean_t);
        den += (i as f64 - mean_i).powi(2);
    }
    (num / den, mean_i, mean_t)
}

/// How far, in steps, the farthest stamp lies from the least-squares line through all of them.
fn stamps_off_line(t: &[f64]) -> f64 {
    let (slope, mean_i, mean_t) = stamp_line(t);
    let farthest =
        t.iter().enumerate().map(|(i, ti)| (ti - mean_t - slope * (i as f64 - mean_i)).abs()).fold(0.0, f64::max);
    farthest / slope
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(t: &[f64]) -> Vec<f64> {
        t.iter().flat_map(|t| [2.0 * t, -t]).collect()
    }

    #[test]
    fn a_uniform_log_comes_back_unchanged() {
        let t: Vec<f64> = (0..100).map(|i| 0.3 + i as f64 * 0.01).collect();
        let q = ramp(&t);
        let out = repair(&t, &[("q", &q, 2)]).unwrap();
        assert_eq!(out, Repaired { t: t.clone(), signals: vec![q], report: vec![] });
    }

    /// Host stamping noise of ±40 % of a step on a uniform stream is left alone: its samples are
    /// uniform, whatever the stamps say.
    #[test]
    fn stamping_noise_is_not_resampled() {
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.005 + 0.0015 * ((i * 7919 % 13) as f64 / 6.0 - 1.0)).collect();
        let q = ramp(&t);
        let out = repair(&t, &[("q", &q, 2)]).unwrap();
        assert!(out.report.is_empty(), "{:?}", out.report);
        assert_eq!(out.t, t);
    }

    /// A leading block stamped by another clock, a sample stamped 2 ms after the previous one,
    /// and a trailing non-finite row: the block and the row are trimmed and named, and the rest
    /// is resampled onto the 10 ms grid, on which a ramp interpolates exactly.
    #[test]
    fn a_corrupt_start_and_end_are_trimmed_and_an_early_sample_resampled() {
        let mut t: Vec<f64> = vec![50.0, 50.01, 50.02];
        t.extend((0..100).map(|i| i as f64 * 0.01));
        t[3 + 40] = t[3 + 39] + 0.002;
        t.push(t[t.len() - 1] + 0.01);
        let mut q = ramp(&t);
        let last = t.len() - 1;
        q[2 * last + 1] = f64::NAN;
        let out = repair(&t, &[("q", &q, 2)]).unwrap();
        assert_eq!(out.report.len(), 3, "{:?}", out.report);
        let start = Choice::Trimmed {
            log: String::new(),
            end: LogEnd::Start,
            first: 0,
            last: 2,
            why: RunBreak::TimeGoesBack { row: 3, from_s: 50.02, to_s: 0.0 },
        };
        assert_eq!(out.report[0], start);
        let end = Choice::Trimmed {
            log: String::new(),
            end: LogEnd::End,
            first: last,
            last,
            why: RunBreak::NotFinite { row: last, signal: "q".into() },
        };
        assert_eq!(out.report[1], end);
        assert!(matches!(out.report[2], Choice::Resampled { first: 3, .. }), "{}", out.report[2]);
        assert_eq!(out.t.len(), 100);
        for (i, (t, q)) in out.t.iter().zip(out.signals[0].chunks(2)).enumerate() {
            assert!((t - i as f64 * 0.01).abs() < 1e-12);
            assert!((q[0] - 2.0 * t).abs() < 1e-12 && (q[1] + t).abs() < 1e-12);
        }
    }

    #[test]
    fn a_break_in_the_middle_is_refused_by_its_rows() {
        let mut t: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
        t[40..].iter_mut().for_each(|x| *x += 1.0); // a gap of 100 steps before row 40
        let q = ramp(&t);
        let error = repair(&t, &[("q", &q, 2)]).unwrap_err().to_string();
        assert!(error.contains("rows 40–99") && error.contains("a gap of 101.0 median steps"), "{error}");
    }

    #[test]
    fn a_signal_of_the_wrong_length_is_named() {
        let t = [0.0, 1.0, 2.0];
        let error = repair(&t, &[("tau", &[0.0; 5], 2)]).unwrap_err();
        assert!(matches!(error, RepairError::Shape { ref name, got: 5, expected: 6, .. } if name == "tau"));
    }
}
