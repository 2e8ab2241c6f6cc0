//! The signal operations preprocessing is made of: splitting a periodic log into its periods
//! (resampled when the period is not a whole number of samples) and averaging them, central
//! differences, and zero-phase filtering of every column.
//!
//! Signals are row-major `N × dof` slices. A periodic signal is one whole period (or several
//! whole periods end to end) and is differenced and filtered circularly: it has no ends.

use super::filter::{Butterworth, FilterError};

/// How a log is averaged: over `count` periods of `samples` samples each (fractional: the period
/// need not be a whole number of samples).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Averaging {
    pub count: usize,
    pub samples: f64,
}

impl Averaging {
    /// Samples in one averaged period.
    pub fn per(self) -> usize {
        self.samples.round() as usize
    }
}

/// The log's periods, each resampled at `per()` evenly spaced points by cubic (Catmull–Rom)
/// interpolation, whose error on a signal sampled well above its bandwidth is far below encoder
/// resolution. A period of a whole number of samples is copied exactly (every point falls on a
/// sample).
pub fn periods_of(x: &[f64], dof: usize, a: Averaging) -> Vec<Vec<f64>> {
    let n = x.len() / dof;
    let points = a.per();
    let step = a.samples / points as f64;
    let at = |i: isize, j: usize| x[(i.clamp(0, n as isize - 1) as usize) * dof + j];
    (0..a.count)
        .map(|p| {
            let mut period = vec![0.0; points * dof];
            for i in 0..points {
                let position = p as f64 * a.samples + i as f64 * step;
                let (k, u) = (position.floor() as isize, position.fract());
                for j in 0..dof {
                    period[i * dof + j] = match u {
                        0.0 => at(k, j),
                        _ => {
                            let (a, b, c, d) = (at(k - 1, j), at(k, j), at(k + 1, j), at(k + 2, j));
                            b + 0.5 * u * (c - a + u * (2.0 * a - 5.0 * b + 4.0 * c - d + u * (3.0 * (b - c) + d - a)))
                        }
                    };
                }
            }
            period
        })
        .collect()
}

/// The sample-by-sample mean of `f` of equally long periods. Averaging `P` periods divides
/// uncorrelated noise variance by `P`.
pub fn mean_of<P: AsRef<[f64]>>(periods: &[P], f: impl Fn(f64) -> f64) -> Vec<f64> {
    let mut mean = vec![0.0; periods.first().map_or(0, |p| p.as_ref().len())];
    for period in periods {
        mean.iter_mut().zip(period.as_ref()).for_each(|(m, v)| *m += f(*v) / periods.len() as f64);
    }
    mean
}

/// The log's periods end to end, each of `per()` samples: `x`'s own first samples (borrowed)
/// when the period is a whole number of samples and the log holds all of them, else
/// [`periods_of`] placed end to end.
pub fn whole_periods(x: &[f64], dof: usize, a: Averaging) -> std::borrow::Cow<'_, [f64]> {
    let length = a.count * a.per() * dof;
    if a.samples == a.per() as f64 && x.len() >= length {
        x[..length].into()
    } else {
        periods_of(x, dof, a).concat().into()
    }
}

/// `x` averaged over its periods, or `x` itself (borrowed, not copied) when not periodic.
pub fn averaged(x: &[f64], dof: usize, averaging: Option<Averaging>) -> std::borrow::Cow<'_, [f64]> {
    match averaging {
        None => x.into(),
        Some(a) => {
            let whole = whole_periods(x, dof, a);
            let mut mean = vec![0.0; a.per() * dof];
            for period in whole.chunks(mean.len()) {
                mean.iter_mut().zip(period).for_each(|(m, v)| *m += v);
            }
            mean.iter_mut().for_each(|m| *m /= a.count as f64);
            mean.into()
        }
    }
}

/// Central differences `(x[k+1] − x[k−1]) / 2h`; circular when `periodic`, one-sided at the ends
/// otherwise.
pub fn central_difference(x: &[f64], dof: usize, h: f64, periodic: bool) -> Vec<f64> {
    let n = x.len() / dof;
    let mut d = vec![0.0; x.len()];
    // The inside in one pass over whole rows, which the compiler vectorises; the two end rows
    // as the ends say.
    if n > 2 {
        let inside = d[dof..(n - 1) * dof].iter_mut().zip(&x[2 * dof..]).zip(&x[..(n - 2) * dof]);
        inside.for_each(|((out, next), prev)| *out = (next - prev) / (2.0 * h));
    }
    for k in [0, n.saturating_sub(1)].into_iter().take(n.min(2)) {
        let (prev, next, span) = match (k, periodic) {
            (0, true) => (n - 1, 1, 2.0),
            (k, true) if k == n - 1 => (k - 1, 0, 2.0),
            (0, false) => (0, 1, 1.0),
            (k, false) if k == n - 1 => (k - 1, k, 1.0),
            (k, _) => (k - 1, k + 1, 2.0),
        };
        for j in 0..dof {
            d[k * dof + j] = (x[next * dof + j] - x[prev * dof + j]) / (span * h);
        }
    }
    d
}

/// Filter every column; a periodic signal is filtered as three copies end to end and the middle
/// copy kept, so that the filter sees no ends.
pub fn filter_columns(filter: &Butterworth, x: &[f64], dof: usize, periodic: bool) -> Result<Vec<f64>, FilterError> {
    let mut out = vec![0.0; x.len()];
    match periodic {
        true => filter.filtfilt_rows_periodic(x, dof, &mut out)?,
        false => filter.filtfilt_rows(x, dof, &mut out)?,
    }
    Ok(out)
}

/// Every `step`-th row of a row-major signal of `width` columns.
pub fn every_nth_row(x: &[f64], width: usize, step: usize) -> Vec<f64> {
    x.chunks(width).step_by(step).flatten().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fractional_period_is_resampled_on_the_signal() {
        // A sine of 100.4 samples per period, three periods: each is resampled at 100 points.
        let samples = 100.4;
        let x: Vec<f64> = (0..310).map(|i| (2.0 * std::f64::consts::PI * i as f64 / samples).sin()).collect();
        let periods = periods_of(&x, 1, Averaging { count: 3, samples });
        for (p, period) in periods.iter().enumerate() {
            assert_eq!(period.len(), 100);
            for (i, v) in period.iter().enumerate() {
                let exact = (2.0 * std::f64::consts::PI * i as f64 / 100.0).sin();
                assert!((v - exact).abs() < 1e-5, "period {p} point {i}: {v} against {exact}");
            }
        }
    }

    #[test]
    fn differences_are_circular_for_a_period_and_one_sided_at_ends() {
        let x = [0.0, 1.0, 4.0, 9.0];
        assert_eq!(central_difference(&x, 1, 1.0, false), vec![1.0, 2.0, 4.0, 5.0]);
        assert_eq!(central_difference(&x, 1, 1.0, true), vec![-4.0, 2.0, 4.0, -2.0]);
    }
}
