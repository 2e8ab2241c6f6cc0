//! The preprocessing choices made from the data when the user leaves them open: whether the log
//! is periodic and with what period, the low-pass cut-off, and the cut-off of the velocity the
//! Coulomb columns see. Each comes back with its reason, and an uncertain one with a warning, so
//! that the model file, `table()` and every front end can say what was chosen and why
//! (docs/identification.md, "Choices made from the data").
//!
//! Both rules read the positions only: they are what the regressor is built from, and a joint's
//! encoder noise is white where the motion has ended, which gives a floor to measure against.

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

use crate::choices::Choice;
use crate::signal::statistics::mean_and_block_error;

/// Consecutive periods of a periodic log differ by at most this share of the motion's variance
/// (10 % in RMS): far above encoder noise, far below two unrelated stretches of motion (~100 %).
pub const PERIODIC_MISMATCH: f64 = 0.01;

/// A spectral line is motion when its power is at least this many times the noise floor (20 dB):
/// the largest of thousands of noise-only lines stays below ~12 times their median.
pub const SIGNAL_OVER_FLOOR: f64 = 100.0;

/// ... and at least this share of the joint's strongest line (−60 dB of power, 0.1 % of the
/// amplitude): what lies below moves the fit less than the noise does.
pub const SIGNAL_OVER_PEAK: f64 = 1e-6;

/// A detected period counts as whole when the log is at most this many samples short of it.
pub const SHORT_BY: usize = 2;

/// Fewer whole periods than this leave the average noisy enough to say so.
pub const FEW_PERIODS: usize = 4;

/// A period found in the data.
#[derive(Clone, Debug, PartialEq)]
pub struct Period {
    /// Length in samples (fractional: the period need not be a whole number of samples).
    pub samples: f64,
    /// Whole periods in the log.
    pub count: usize,
    /// Mean squared difference between consecutive periods over the motion's variance.
    pub mismatch: f64,
}

/// What [`find_period`] concluded, with the reason in words.
#[derive(Clone, Debug)]
pub struct PeriodSearch {
    pub period: Option<Period>,
    pub reason: Choice,
}

/// Joints whose position moves: the others carry no spectrum or period to read.
fn moving_columns(q: &[f64], dof: usize) -> Vec<Vec<f64>> {
    (0..dof)
        .map(|j| q.iter().skip(j).step_by(dof).copied().collect::<Vec<f64>>())
        .filter(|c| c.iter().any(|v| *v != c[0]))
        .map(|mut c| {
            let mean = c.iter().sum::<f64>() / c.len() as f64;
            c.iter_mut().for_each(|v| *v -= mean);
            c
        })
        .collect()
}

/// `Σ_k x_k x_{k+L}` for every lag `L < n`, by FFT.
fn autocorrelation(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let m = (2 * n).next_power_of_two();
    let mut planner = RealFftPlanner::<f64>::new();
    let (forward, inverse) = (planner.plan_fft_forward(m), planner.plan_fft_inverse(m));
    let mut buffer = vec![0.0; m];
    buffer[..n].copy_from_slice(x);
    let mut spectrum = forward.make_output_vec();
    forward.process(&mut buffer, &mut spectrum).expect("buffer sizes come from the plan");
    spectrum.iter_mut().for_each(|c| *c = Complex::new(c.norm_sqr(), 0.0));
    inverse.process(&mut spectrum, &mut buffer).expect("buffer sizes come from the plan");
    buffer.truncate(n);
    buffer.iter_mut().for_each(|v| *v /= m as f64);
    buffer
}

/// Mean over the moving joints of `Σ (x_k − x_{k+L})² / (2 (n − L) var)` for `L ≤ n/2`: 0 where
/// the motion repeats after `L` samples, about 1 between unrelated stretches.
fn mismatch_by_lag(columns: &[Vec<f64>]) -> Vec<f64> {
    let n = columns[0].len();
    let half = n / 2;
    let mut mismatch = vec![0.0; half + 1];
    for x in columns {
        let r = autocorrelation(x);
        let mut prefix = vec![0.0; n + 1];
        for (i, v) in x.iter().enumerate() {
            prefix[i + 1] = prefix[i] + v * v;
        }
        let var = prefix[n] / n as f64;
        for (lag, m) in mismatch.iter_mut().enumerate().skip(1) {
            let squares = prefix[n - lag] + (prefix[n] - prefix[lag]);
            *m += (squares - 2.0 * r[lag]).max(0.0) / (2.0 * (n - lag) as f64 * var) / columns.len() as f64;
        }
    }
    mismatch
}

/// `Σ f(aₖ, bₖ)` in four interleaved sums: one sum waits on its every addition, and over a long
/// log's 10⁶ samples that wait was most of checking the periods a user gave.
fn sum_of_pairs(a: &[f64], b: &[f64], f: impl Fn(f64, f64) -> f64) -> f64 {
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4.remainder().iter().zip(b4.remainder()).map(|(x, y)| f(*x, *y)).sum();
    let mut sums = [0.0; 4];
    for (x, y) in a4.zip(b4) {
        for l in 0..4 {
            sums[l] += f(x[l], y[l]);
        }
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3]) + tail
}

/// The same mismatch at one lag, summed directly (for lags beyond `n/2`).
fn mismatch_at(columns: &[Vec<f64>], lag: usize) -> f64 {
    let n = columns[0].len();
    columns
        .iter()
        .map(|x| {
            let var = sum_of_pairs(x, x, |v, _| v * v) / n as f64;
            let d = sum_of_pairs(&x[..n - lag], &x[lag..], |a, b| (a - b).powi(2));
            d / (2.0 * (n - lag) as f64 * var)
        })
        .sum::<f64>()
        / columns.len() as f64
}

/// The mismatch between the positions (`N × dof`, row-major) and themselves `lag` samples later.
pub fn mismatch_of_columns(q: &[f64], dof: usize, lag: usize) -> f64 {
    let columns = moving_columns(q, dof);
    if columns.is_empty() || lag >= columns[0].len() {
        return f64::NAN;
    }
    mismatch_at(&columns, lag)
}

/// The vertex of the parabola through three equally spaced points, as an offset from the middle
/// one (in steps); 0 where they are collinear.
fn parabola_vertex(left: f64, middle: f64, right: f64) -> f64 {
    let curvature = left - 2.0 * middle + right;
    if curvature > 0.0 {
        (0.5 * (left - right) / curvature).clamp(-0.5, 0.5)
    } else {
        0.0
    }
}

/// The period of a periodic log (`q`: `N × dof`, row-major, at `fs` Hz), or why there is none.
///
/// The shortest lag after which the motion repeats to within [`PERIODIC_MISMATCH`], searched
/// among lags where the motion has first moved away from itself (so that a slow signal is not
/// "periodic" at a lag of one sample). The lag is then refined over the longest whole multiple
/// the log holds, which brings the error to a fraction of a sample over the whole log.
pub fn find_period(q: &[f64], dof: usize, fs: f64) -> PeriodSearch {
    let columns = moving_columns(q, dof);
    let aperiodic = |reason: Choice| PeriodSearch { period: None, reason };
    if columns.is_empty() || columns[0].len() < 8 {
        return aperiodic(Choice::NoJointMoves);
    }
    let n = columns[0].len();
    let mismatch = mismatch_by_lag(&columns);
    let Some(apart) = mismatch.iter().position(|m| *m > 0.5) else {
        return aperiodic(Choice::NeverMovesAway { half_log_s: n as f64 / fs / 2.0 });
    };
    let (best_lag, best) =
        (apart..mismatch.len()).map(|l| (l, mismatch[l])).min_by(|a, b| a.1.total_cmp(&b.1)).expect("apart < len");
    if best > PERIODIC_MISMATCH {
        return aperiodic(Choice::DoesNotRepeat {
            after_s: best_lag as f64 / fs,
            mismatch: best,
            limit: PERIODIC_MISMATCH,
        });
    }
    // The fundamental is the first lag that repeats about as well as the best (a multiple of it).
    let good_enough = (2.0 * best).max(best + 0.1 * PERIODIC_MISMATCH);
    let mut lag = (apart..mismatch.len()).find(|&l| mismatch[l] <= good_enough).expect("best_lag qualifies");
    while lag + 1 < mismatch.len() && mismatch[lag + 1] < mismatch[lag] {
        lag += 1;
    }
    let count = n / lag;
    let samples = refine(&columns, &mismatch, lag, count);
    // A log cut a sample or two short of its last period still holds it: the missing samples are
    // the next period's first, which the ends' clamping in averaging stands in for.
    let count = ((n + SHORT_BY) as f64 / samples).floor() as usize;
    PeriodSearch {
        period: Some(Period { samples, count, mismatch: mismatch[lag] }),
        reason: Choice::PeriodsFound { count, period_s: samples / fs, mismatch: mismatch[lag] },
    }
}

/// The period to a fraction of a sample: the minimum of the mismatch at the longest whole
/// multiple of `lag` the log holds, divided by that multiple.
fn refine(columns: &[Vec<f64>], mismatch: &[f64], lag: usize, count: usize) -> f64 {
    let multiple = count.saturating_sub(1).max(1);
    let centre = lag * multiple;
    let at = |l: usize| if l < mismatch.len() { mismatch[l] } else { mismatch_at(columns, l) };
    let n = columns[0].len();
    let candidates = (centre.saturating_sub(multiple).max(1)..=(centre + multiple).min(n - 2)).collect::<Vec<_>>();
    let values: Vec<f64> = candidates.iter().map(|&l| at(l)).collect();
    let i = values.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).map_or(0, |(i, _)| i);
    let offset =
        if i > 0 && i + 1 < values.len() { parabola_vertex(values[i - 1], values[i], values[i + 1]) } else { 0.0 };
    let samples = (candidates[i] as f64 + offset) / multiple as f64;
    // A period within a thousandth of a sample of a whole number is that number: averaging then
    // needs no interpolation.
    if (samples - samples.round()).abs() < 1e-3 {
        samples.round()
    } else {
        samples
    }
}

/// Power spectrum of each moving joint's position, pre-whitened by a first difference so that
/// a window's leakage from the large low-frequency lines cannot mask the small high ones, then
/// divided back by the difference's gain. A periodic average is one exact period: its DFT lines
/// are the harmonics, with no window. Otherwise Welch's estimate with a Hann window.
fn position_spectra(q: &[f64], dof: usize, fs: f64, periodic: bool) -> (Vec<f64>, Vec<Vec<f64>>) {
    let columns = moving_columns(q, dof);
    let n = columns.first().map_or(0, Vec::len);
    let segment = if periodic { n } else { n.min((20.0 * fs) as usize).max(16) };
    let segment = segment - segment % 2;
    let step = segment / 2;
    let window: Vec<f64> = match periodic {
        true => vec![1.0; segment],
        false => (0..segment).map(|i| (std::f64::consts::PI * i as f64 / segment as f64).sin().powi(2)).collect(),
    };
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(segment);
    let frequencies: Vec<f64> = (0..=segment / 2).map(|k| k as f64 * fs / segment as f64).collect();
    let spectra = columns
        .iter()
        .map(|x| {
            let diff: Vec<f64> = match periodic {
                true => (0..n).map(|k| x[(k + 1) % n] - x[k]).collect(),
                false => x.windows(2).map(|w| w[1] - w[0]).collect(),
            };
            let mut power = vec![0.0; segment / 2 + 1];
            let starts: Vec<usize> = (0..).map(|s| s * step).take_while(|s| s + segment <= diff.len()).collect();
            let starts = if starts.is_empty() { vec![0] } else { starts };
            for &start in &starts {
                let mut buffer: Vec<f64> = (0..segment).map(|i| diff.get(start + i).copied().unwrap_or(0.0)).collect();
                let mean = buffer.iter().sum::<f64>() / segment as f64;
                buffer.iter_mut().zip(&window).for_each(|(v, w)| *v = (*v - mean) * w);
                let mut spectrum = fft.make_output_vec();
                fft.process(&mut buffer, &mut spectrum).expect("buffer sizes come from the plan");
                power.iter_mut().zip(&spectrum).for_each(|(p, c)| *p += c.norm_sqr());
            }
            for (k, p) in power.iter_mut().enumerate().skip(1) {
                let gain = 2.0 * (std::f64::consts::PI * k as f64 / segment as f64).sin();
                *p /= starts.len() as f64 * gain * gain;
            }
            power[0] = 0.0;
            power
        })
        .collect();
    (frequencies, spectra)
}

/// The highest frequency where any joint's motion stands out of its position spectrum (Hz). The
/// noise floor is the median power over the top half of the band, where trajectories have no
/// content; a line is motion above [`SIGNAL_OVER_FLOOR`] times it and [`SIGNAL_OVER_PEAK`] times
/// the joint's strongest line. `None` when no joint moves.
///
/// Encoder quantisation is not white noise (a slow joint's error is a staircase whose content
/// sits near its crossing rate), so where the floor is reached is not itself used for anything:
/// the relative threshold keeps that structure out of the bandwidth.
pub fn bandwidth(q: &[f64], dof: usize, fs: f64, periodic: bool) -> Option<f64> {
    let (frequencies, spectra) = position_spectra(q, dof, fs, periodic);
    let lines = frequencies.len();
    let mut signal_hz = f64::NAN;
    for power in &spectra {
        let mut upper: Vec<f64> = power[lines / 2..].to_vec();
        let middle = upper.len() / 2;
        let floor = *upper.select_nth_unstable_by(middle, f64::total_cmp).1;
        let peak = power.iter().copied().fold(0.0, f64::max);
        let threshold = (SIGNAL_OVER_FLOOR * floor).max(SIGNAL_OVER_PEAK * peak);
        // f64::max ignores the NaN it starts from.
        if let Some(f) = power.iter().rposition(|p| *p >= threshold && *p > 0.0).map(|k| frequencies[k]) {
            signal_hz = signal_hz.max(f);
        }
    }
    (!signal_hz.is_nan()).then_some(signal_hz)
}

/// Lines on each side over which the between-period noise is pooled: its per-line estimate from
/// a few periods scatters by a factor of several, a median over 17 lines by far less.
const FLOOR_HALF_WIDTH: usize = 8;

/// The highest harmonic of a periodic log that repeats from period to period (Hz): the average
/// of the periods' spectra stands above the scatter between them by [`SIGNAL_OVER_FLOOR`] (and
/// above [`SIGNAL_OVER_PEAK`] of the joint's strongest line). `periods` are the log's periods,
/// each resampled to the same `points × dof` samples at `fs`.
///
/// What differs between periods (a controller's dither, torque-noise-driven motion, encoder
/// noise) is measured here, at every frequency, rather than assumed white: a closed-loop log's
/// dither stands far above the encoder's floor, but not above its own scatter.
pub fn harmonic_bandwidth(periods: &[Vec<f64>], dof: usize, fs: f64) -> Option<f64> {
    let count = periods.len();
    let points = periods.first()?.len() / dof;
    if count < 2 || points < 8 {
        return None;
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(points);
    let lines = points / 2 + 1;
    let mut signal_hz = f64::NAN;
    for j in 0..dof {
        let spectra: Vec<Vec<Complex<f64>>> = periods
            .iter()
            .map(|x| {
                // Pre-whitened like `position_spectra`, against leakage from a period that is not
                // exactly a whole number of samples.
                let mut diff: Vec<f64> =
                    (0..points).map(|k| x[((k + 1) % points) * dof + j] - x[k * dof + j]).collect();
                let mut spectrum = fft.make_output_vec();
                fft.process(&mut diff, &mut spectrum).expect("buffer sizes come from the plan");
                spectrum
            })
            .collect();
        let mean: Vec<Complex<f64>> =
            (0..lines).map(|k| spectra.iter().map(|s| s[k]).sum::<Complex<f64>>() / count as f64).collect();
        // Variance of the mean at each line, from the scatter of the periods about it.
        let scatter: Vec<f64> = (0..lines)
            .map(|k| spectra.iter().map(|s| (s[k] - mean[k]).norm_sqr()).sum::<f64>() / ((count - 1) * count) as f64)
            .collect();
        // Back to position units (the difference's gain), where lines compare with the peak.
        let gain =
            |k: usize| (2.0 * (std::f64::consts::PI * k as f64 / points as f64).sin()).powi(2).max(f64::MIN_POSITIVE);
        let scatter: Vec<f64> = scatter.iter().enumerate().map(|(k, v)| v / gain(k)).collect();
        let power: Vec<f64> = mean.iter().enumerate().map(|(k, c)| c.norm_sqr() / gain(k)).collect();
        let peak = power.iter().skip(1).copied().fold(0.0, f64::max);
        if peak == 0.0 {
            continue;
        }
        let repeats = |k: usize| {
            let mut window: Vec<f64> =
                scatter[k.saturating_sub(FLOOR_HALF_WIDTH).max(1)..(k + FLOOR_HALF_WIDTH + 1).min(lines)].to_vec();
            let middle = window.len() / 2;
            let floor = *window.select_nth_unstable_by(middle, f64::total_cmp).1;
            power[k] >= SIGNAL_OVER_FLOOR * floor && power[k] >= SIGNAL_OVER_PEAK * peak
        };
        if let Some(k) = (1..lines).rev().find(|&k| repeats(k)) {
            signal_hz = signal_hz.max(k as f64 * fs / points as f64);
        }
    }
    (!signal_hz.is_nan()).then_some(signal_hz)
}

/// Cut-offs tried per doubling: a step of 19 %, which changes the fit by far less than a point.
pub const CUTOFFS_PER_OCTAVE: usize = 4;

/// Geometric steps, [`CUTOFFS_PER_OCTAVE`] per octave, from `floor` to the last one at or below
/// `top` (at least `floor`).
pub fn geometric_grid(floor: f64, top: f64) -> Vec<f64> {
    let step = 2f64.powf(1.0 / CUTOFFS_PER_OCTAVE as f64);
    let count = ((top / floor).log2() * CUTOFFS_PER_OCTAVE as f64 + 1e-9).floor().max(0.0) as usize;
    (0..=count).map(|i| floor * step.powi(i as i32)).collect()
}

/// A cut-off predicts as well as the best when its prediction's extra squared error is within
/// this many standard errors of nothing (a one-sided test at about 2 %). Among those, the one
/// whose model explains its own filtered torque best is kept: usually the lowest, which takes the
/// most noise out of the signals without losing what the model explains.
pub const EQUAL_PREDICTION_SIGMAS: f64 = 2.0;

/// ... and no more than this many points of mean FP% below it: a difference the test cannot
/// resolve on a short or badly explained log is still not ignored when it is this large (the
/// issue's own notion of fitting "as well").
pub const EQUAL_PREDICTION_POINTS: f64 = 1.0;

/// A candidate cut-off, judged by how well the model fitted at it predicts torque it was not
/// filtered toward: identification's cut-off (`signal/cutoff.rs`) and the diagnosis's band
/// (`diagnose/band.rs`) are both chosen by [`best_predicting`] over these.
#[derive(Clone, Copy, Debug)]
pub struct Prediction<'a> {
    pub cutoff_hz: f64,
    /// The prediction's squared error at each scored sample, each joint's over its torque's
    /// variance, summed over the joints; every candidate is scored at the same samples.
    pub errors: &'a [f64],
    /// Mean FP% of that prediction.
    pub fp: f64,
    /// Mean FP% of the model on its own filtered torque: what breaks ties.
    pub training_fp: f64,
}

/// The candidate whose prediction has the highest mean FP%.
pub fn most_accurate_prediction(candidates: &[Prediction]) -> Option<usize> {
    (0..candidates.len()).max_by(|&a, &b| candidates[a].fp.total_cmp(&candidates[b].fp))
}

/// How close a candidate's prediction must come to the best's to count as equal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Equal {
    /// Its extra squared error over the best's within [`EQUAL_PREDICTION_SIGMAS`] standard errors
    /// of the paired difference (blocks of `block_rows` scored samples, over which the errors are
    /// correlated), and its mean FP% within [`EQUAL_PREDICTION_POINTS`] of it (identification:
    /// the finest distinction the data allow, for the parameters' sake).
    Paired { block_rows: usize },
    /// Its mean squared error within [`EQUAL_PREDICTION_SIGMAS`] of the best's own sampling
    /// errors, a relative √(2/n) over `independent` = n held-out samples (the diagnosis): another
    /// log of the robot would score the bands with that scatter, so bands closer than that are
    /// no choice the data make. The paired test resolves far finer differences where the declared
    /// model is nearly right (0.01 points of FP% between two bands of a clean log), which move
    /// no diagnosis.
    Sampling { independent: f64 },
}

/// Which candidates predict as well as the best, by `equal`.
pub fn as_good_as_best(candidates: &[Prediction], equal: Equal) -> Vec<bool> {
    let Some(best) = most_accurate_prediction(candidates).map(|i| candidates[i]) else { return vec![] };
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len().max(1) as f64;
    candidates
        .iter()
        .map(|c| match equal {
            Equal::Paired { block_rows } => {
                let differences: Vec<f64> = c.errors.iter().zip(best.errors).map(|(a, b)| a - b).collect();
                let (mean, error) = mean_and_block_error(&differences, block_rows);
                mean <= EQUAL_PREDICTION_SIGMAS * error && c.fp >= best.fp - EQUAL_PREDICTION_POINTS
            }
            Equal::Sampling { independent } => {
                let relative = (2.0 / independent.max(1.0)).sqrt();
                mean(c.errors) <= mean(best.errors) * (1.0 + EQUAL_PREDICTION_SIGMAS * relative)
            }
        })
        .collect()
}

/// Which of the cut-offs that predict alike a search keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Prefer {
    /// The one whose model fits its own filtered torque best (identification): equal predictions
    /// hold the same predictable content, and the best in-band fit holds the least of what no
    /// model predicts (noise, and what the model lacks above the motion), so the parameters
    /// come out with the least spread.
    BestInBandFit,
    /// The widest (the diagnosis): equal predictions hold the same predictable content, and a
    /// wider band holds more of the motion's information in more independent samples, for the
    /// Wald test's batches and for telling effects apart (a drive's gain from a mass on the link
    /// it lifts, which differ only in the faster dynamics).
    Widest,
}

/// The cut-off to use: of those that predict as well as the best ([`as_good_as_best`]), the one
/// `prefer` names. `None` when there are no candidates.
pub fn best_predicting(candidates: &[Prediction], equal: Equal, prefer: Prefer) -> Option<usize> {
    let good = as_good_as_best(candidates, equal);
    let equal = (0..candidates.len()).filter(|&i| good[i]);
    match prefer {
        Prefer::BestInBandFit => equal.max_by(|&a, &b| candidates[a].training_fp.total_cmp(&candidates[b].training_fp)),
        Prefer::Widest => equal.max_by(|&a, &b| candidates[a].cutoff_hz.total_cmp(&candidates[b].cutoff_hz)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_steps_geometrically_from_the_floor_to_the_top() {
        let c = geometric_grid(1.0, 8.0);
        assert_eq!(c.len(), 13, "{c:?}");
        assert!((c[0] - 1.0).abs() < 1e-12 && (c[12] - 8.0).abs() < 1e-9);
        assert!(c.windows(2).all(|w| (w[1] / w[0] - 2f64.powf(0.25)).abs() < 1e-12));
        assert_eq!(geometric_grid(1.0, 0.5), vec![1.0]);
    }

    /// Three cut-offs scored on 400 samples: the best, one whose extra error is a fraction of a
    /// standard error (equal), and one clearly worse. Of the two equal ones identification keeps
    /// the one that fits its own torque best, whichever predicts a little better; the diagnosis
    /// the wider; the clearly worse one is neither's, wide as it is and well as it fits.
    #[test]
    fn of_the_equal_predictions_the_best_in_band_fit_is_chosen() {
        let noise = |i: usize, seed: usize| ((i * 7919 + seed * 104_729) % 1000) as f64 / 1000.0;
        let base: Vec<f64> = (0..400).map(|i| 0.1 + 0.05 * noise(i, 1)).collect();
        // Scattered about the best's with no mean difference.
        let mean = (0..400).map(|i| noise(i, 2)).sum::<f64>() / 400.0;
        let equal: Vec<f64> = (0..400).map(|i| base[i] + 0.002 * (noise(i, 2) - mean)).collect();
        let worse: Vec<f64> = base.iter().map(|b| b + 0.05).collect();
        let candidates = [
            Prediction { cutoff_hz: 2.0, errors: &equal, fp: 90.0, training_fp: 95.0 },
            Prediction { cutoff_hz: 4.0, errors: &base, fp: 90.1, training_fp: 94.0 },
            Prediction { cutoff_hz: 8.0, errors: &worse, fp: 85.0, training_fp: 99.0 },
        ];
        let paired = Equal::Paired { block_rows: 20 };
        assert_eq!(as_good_as_best(&candidates, paired), vec![true, true, false]);
        assert_eq!(best_predicting(&candidates, paired, Prefer::BestInBandFit), Some(0));
        assert_eq!(best_predicting(&candidates, paired, Prefer::Widest), Some(1));
        // The worse one's mean squared error is 40 % above the best's: equal only where the best's
        // own sampling error is that large (a handful of independent samples).
        assert_eq!(as_good_as_best(&candidates, Equal::Sampling { independent: 400.0 }), vec![true, true, false]);
        assert_eq!(as_good_as_best(&candidates, Equal::Sampling { independent: 8.0 }), vec![true, true, true]);
    }

    /// `dof` joints of a Fourier series with period `period_s` (harmonics 1..=5 of it), sampled
    /// at `fs` for `duration_s`, quantised to `bits` over one turn.
    fn fourier_log(fs: f64, period_s: f64, duration_s: f64, bits: u32) -> Vec<f64> {
        let w = 2.0 * std::f64::consts::PI / period_s;
        let quantum = 2.0 * std::f64::consts::PI / f64::from(1u32 << bits);
        let n = (fs * duration_s) as usize;
        (0..n)
            .flat_map(|i| {
                let t = i as f64 / fs;
                (0..3).map(move |j| {
                    let q: f64 = (1..=5).map(|h| 0.2 / h as f64 * (h as f64 * w * t + j as f64 + h as f64).sin()).sum();
                    (q / quantum).round() * quantum
                })
            })
            .collect()
    }

    #[test]
    fn the_period_of_a_quantised_fourier_log_is_found_to_a_fraction_of_a_sample() {
        // 10 s at 1 kHz (a whole number of samples) and 7.3 s at 200 Hz (1,460 samples) and
        // 3.33 s at 100 Hz (333 samples): a third of a sample per period short.
        for (fs, period, duration, expected_count) in
            [(1000.0, 10.0, 80.0, 8), (200.0, 7.3, 30.0, 4), (100.0, 3.3333, 40.0, 12)]
        {
            let q = fourier_log(fs, period, duration, 16);
            let found = find_period(&q, 3, fs);
            let p = found.period.unwrap_or_else(|| panic!("{fs} Hz: {}", found.reason));
            assert!((p.samples / fs - period).abs() < 1e-3 / fs * 10.0, "{fs} Hz: {} s", p.samples / fs);
            assert_eq!(p.count, expected_count, "{}", found.reason);
        }
    }

    #[test]
    fn a_log_without_repeats_is_said_to_be_aperiodic() {
        // Incommensurate frequencies: no lag within half the log brings it back.
        let fs = 500.0;
        let q: Vec<f64> = (0..20_000)
            .flat_map(|i| {
                let t = i as f64 / fs;
                [(0.37 * t).sin() + (1.0 * t * std::f64::consts::E).sin(), (0.23 * t * 2f64.sqrt()).cos()]
            })
            .collect();
        let found = find_period(&q, 2, fs);
        assert!(found.period.is_none(), "{:?}", found.period);
        let aperiodic = matches!(found.reason, Choice::NeverMovesAway { .. } | Choice::DoesNotRepeat { .. });
        assert!(aperiodic, "{}", found.reason);
    }

    #[test]
    fn the_bandwidth_is_the_highest_harmonic_however_fine_the_encoder() {
        // Harmonics up to 0.5 Hz, at 100 Hz to 5 kHz, 12- to 20-bit encoders, periodic or not.
        for fs in [100.0, 1000.0, 5000.0] {
            for bits in [12, 16, 20] {
                let q = fourier_log(fs, 10.0, 40.0, bits);
                let b = bandwidth(&q, 3, fs, false).unwrap();
                assert!((0.45..=0.75).contains(&b), "{fs} Hz {bits} bit: {b} Hz");
                let period = &q[..(10.0 * fs) as usize * 3];
                let b = bandwidth(period, 3, fs, true).unwrap();
                assert!((b - 0.5).abs() < 1e-9, "{fs} Hz {bits} bit periodic: {b} Hz");
            }
        }
    }
}
