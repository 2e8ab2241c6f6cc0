//! From a logged run to the signals identification uses (paper section III-C): average the
//! periods of a periodic excitation, low-pass filter with a zero-phase Butterworth, and take
//! central differences for q̇ and q̈, filtered the same way. Torque is averaged and filtered alike.
//!
//! Signals are row-major `N × dof` slices in SI units. A periodic average is filtered and
//! differentiated circularly (three periods side by side, the middle kept): one period of a
//! periodic signal has no ends, so it gets no end effects.

use super::filter::{Butterworth, FilterError};

/// Settings for [`preprocess`]. `Default` gives the paper's: order 5, cut-off from the bandwidth.
#[derive(Clone, Debug)]
pub struct PreprocessOptions {
    /// Number of whole excitation periods in the log; `None` means not periodic (no averaging).
    pub periods: Option<usize>,
    /// Low-pass cut-off (Hz); `None` derives it from the trajectory's bandwidth (see
    /// [`default_cutoff_hz`]).
    pub cutoff_hz: Option<f64>,
    /// Butterworth order, applied forward and backward.
    pub order: usize,
    /// Keep every `decimate`-th sample after filtering (1 keeps all).
    pub decimate: usize,
    /// Cut-off of the velocity that switches Coulomb friction (Hz); `None` gives
    /// [`DEFAULT_FRICTION_CUTOFF_HZ`] (never below the main cut-off).
    pub friction_cutoff_hz: Option<f64>,
    /// Filter q̇ and q̈ again after each central difference (the paper's method). Off, the
    /// derivatives of the filtered position pass through the filter once, exactly as the torque
    /// does, which matters when the signals have content near the cut-off (the diagnosis).
    pub filter_derivatives: bool,
}

/// Friction switches with the joint's actual velocity, which under closed-loop control dithers
/// around zero far faster than the trajectory's bandwidth. A velocity filtered at the main
/// cut-off (a few Hz) crosses zero cleanly and misses that (docs/identification.md gives what it
/// costs). 20 Hz keeps the dither and still rejects most encoder quantisation noise.
pub const DEFAULT_FRICTION_CUTOFF_HZ: f64 = 20.0;

impl Default for PreprocessOptions {
    fn default() -> Self {
        Self {
            periods: None,
            cutoff_hz: None,
            order: 5,
            decimate: 1,
            friction_cutoff_hz: None,
            filter_derivatives: true,
        }
    }
}

/// Why a log cannot be preprocessed. Each variant names the offending input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PreprocessError {
    #[error("{name} has {got} values, expected {expected} ({samples} samples × {width})")]
    Shape { name: &'static str, got: usize, expected: usize, samples: usize, width: usize },
    #[error("{name} is not finite at sample {sample}")]
    NotFinite { name: &'static str, sample: usize },
    #[error("need at least {needed} samples, got {got}")]
    TooFewSamples { needed: usize, got: usize },
    #[error("t is not uniformly sampled: step {index} is {step:.6} s where the median step is {median:.6} s")]
    NonUniformTime { index: usize, step: f64, median: f64 },
    #[error("{periods} period(s) requested: averaging needs at least 2 whole periods")]
    TooFewPeriods { periods: usize },
    #[error("decimation factor must be at least 1")]
    BadDecimation,
    #[error(
        "decimating by {factor} leaves a Nyquist frequency of {nyquist_hz} Hz, not above the {cutoff_hz} Hz cut-off"
    )]
    DecimationAliases { factor: usize, nyquist_hz: f64, cutoff_hz: f64 },
    #[error(transparent)]
    Filter(#[from] FilterError),
}

/// Preprocessed signals, row-major `samples × dof`, ready for the regressor.
#[derive(Clone, Debug)]
pub struct Preprocessed {
    pub dof: usize,
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    /// The velocity that switches Coulomb friction: filtered at `friction_cutoff_hz`.
    pub qd_friction: Vec<f64>,
    pub tau: Vec<f64>,
    /// The cut-off actually used (Hz).
    pub cutoff_hz: f64,
    /// Sample rate of the input (Hz).
    pub sample_rate_hz: f64,
    /// Periods averaged (1 when not periodic).
    pub periods_averaged: usize,
    /// Butterworth order used.
    pub order: usize,
    /// Whether the signals are one period of a periodic average (filtered circularly).
    pub periodic: bool,
    /// Decimation factor applied after filtering.
    pub decimate: usize,
}

impl Preprocessed {
    pub fn samples(&self) -> usize {
        self.t.len()
    }

    /// Rate of the preprocessed samples (Hz): the input rate over the decimation factor.
    pub fn rate_hz(&self) -> f64 {
        self.sample_rate_hz / self.decimate as f64
    }

    /// Filter an extra `samples × width` signal exactly as the torque was filtered (circularly for
    /// a periodic average). Decimated data cannot be filtered again at the original rate.
    pub fn filter_like_torque(&self, x: &[f64], width: usize) -> Result<Vec<f64>, FilterError> {
        let filter = Butterworth::lowpass(self.order, self.cutoff_hz, self.rate_hz())?;
        filter_columns(&filter, x, width, self.periodic)
    }
}

/// Check shapes, finiteness and uniform sampling; return the sample period.
pub fn validate_log(t: &[f64], q: &[f64], tau: &[f64], dof: usize) -> Result<f64, PreprocessError> {
    let n = t.len();
    for (name, values) in [("q", q), ("tau", tau)] {
        if values.len() != n * dof {
            return Err(PreprocessError::Shape { name, got: values.len(), expected: n * dof, samples: n, width: dof });
        }
    }
    for (name, values, width) in [("t", t, 1), ("q", q, dof), ("tau", tau, dof)] {
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(PreprocessError::NotFinite { name, sample: i / width });
        }
    }
    if n < 64 {
        return Err(PreprocessError::TooFewSamples { needed: 64, got: n });
    }
    let step = |w: &[f64]| w[1] - w[0];
    let mut steps: Vec<f64> = t.windows(2).map(step).collect();
    let middle = steps.len() / 2;
    let median = *steps.select_nth_unstable_by(middle, f64::total_cmp).1;
    // Logged timestamps jitter; a step more than 1 % off the median is a gap or a reordering.
    // `steps` is reordered by the selection, so the first such step is found in `t` itself.
    if let Some((index, step)) = t.windows(2).map(step).enumerate().find(|(_, s)| (s - median).abs() > 0.01 * median) {
        return Err(PreprocessError::NonUniformTime { index, step, median });
    }
    if median <= 0.0 {
        return Err(PreprocessError::NonUniformTime { index: 0, step: median, median });
    }
    Ok(median)
}

/// Run the whole pipeline on a log (`t`: N; `q`, `tau`: N × dof, row-major).
pub fn preprocess(
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    dof: usize,
    options: &PreprocessOptions,
) -> Result<Preprocessed, PreprocessError> {
    let dt = validate_log(t, q, tau, dof)?;
    if options.decimate == 0 {
        return Err(PreprocessError::BadDecimation);
    }
    let fs = 1.0 / dt;
    let (periodic, periods) = match options.periods {
        Some(p) if p < 2 => return Err(PreprocessError::TooFewPeriods { periods: p }),
        Some(p) => (true, p),
        None => (false, 1),
    };
    let averaged = |x| averaged(x, dof, periods, t.len() / periods);
    // q is needed for the cut-off and by both chains below; τ only by its own, which averages it.
    let q = averaged(q);
    let n = t.len() / periods;
    let cutoff_hz = match options.cutoff_hz {
        Some(c) => c,
        None => default_cutoff_hz(&q, dof, fs, periodic),
    };
    let filter = Butterworth::lowpass(options.order, cutoff_hz, fs)?;
    let decimated_nyquist = 0.5 * fs / options.decimate as f64;
    if cutoff_hz >= decimated_nyquist {
        return Err(PreprocessError::DecimationAliases {
            factor: options.decimate,
            nyquist_hz: decimated_nyquist,
            cutoff_hz,
        });
    }
    let friction_cutoff_hz =
        options.friction_cutoff_hz.unwrap_or(DEFAULT_FRICTION_CUTOFF_HZ).max(cutoff_hz).min(0.25 * fs);
    let friction_filter = Butterworth::lowpass(options.order, friction_cutoff_hz, fs)?;
    let positions = || -> Result<_, FilterError> {
        let q_f = filter_columns(&filter, &q, dof, periodic)?;
        let derivative = |x: &[f64]| -> Result<Vec<f64>, FilterError> {
            let d = central_difference(x, dof, dt, periodic);
            if options.filter_derivatives {
                filter_columns(&filter, &d, dof, periodic)
            } else {
                Ok(d)
            }
        };
        let qd = derivative(&q_f)?;
        let qdd = derivative(&qd)?;
        Ok((q_f, qd, qdd))
    };
    let torque_and_friction = || -> Result<_, FilterError> {
        let tau_f = filter_columns(&filter, &averaged(tau), dof, periodic)?;
        let qd_friction = filter_columns(&friction_filter, &central_difference(&q, dof, dt, periodic), dof, periodic)?;
        Ok((tau_f, qd_friction))
    };
    // The two chains are independent; on two cores they take the time of the longer one.
    let (chain, other) = std::thread::scope(|scope| {
        let other = scope.spawn(torque_and_friction);
        (positions(), other.join().expect("filtering does not panic"))
    });
    let ((q_f, qd, qdd), (tau_f, qd_friction)) = (chain?, other?);
    let keep = |x: &[f64]| -> Vec<f64> { x.chunks(dof).step_by(options.decimate).flatten().copied().collect() };
    let t_out: Vec<f64> = (0..n).step_by(options.decimate).map(|i| t[0] + i as f64 * dt).collect();
    Ok(Preprocessed {
        dof,
        t: t_out,
        q: keep(&q_f),
        qd: keep(&qd),
        qdd: keep(&qdd),
        qd_friction: keep(&qd_friction),
        tau: keep(&tau_f),
        cutoff_hz,
        sample_rate_hz: fs,
        periods_averaged: periods,
        order: options.order,
        periodic,
        decimate: options.decimate,
    })
}

/// `x` averaged over its periods, or `x` itself (borrowed, not copied) for a single period.
fn averaged(x: &[f64], dof: usize, periods: usize, per: usize) -> std::borrow::Cow<'_, [f64]> {
    match periods {
        1 => x.into(),
        _ => average_periods(x, dof, periods, per).into(),
    }
}

/// Mean over `periods` consecutive blocks of `per` samples (trailing samples beyond whole periods
/// are dropped). Averaging `P` periods divides uncorrelated noise variance by `P`.
pub fn average_periods(x: &[f64], dof: usize, periods: usize, per: usize) -> Vec<f64> {
    let mut mean = vec![0.0; per * dof];
    for p in 0..periods {
        for (m, v) in mean.iter_mut().zip(&x[p * per * dof..(p + 1) * per * dof]) {
            *m += v;
        }
    }
    mean.iter_mut().for_each(|m| *m /= periods as f64);
    mean
}

/// Central differences `(x[k+1] − x[k−1]) / 2h`; circular when `periodic`, one-sided at the ends
/// otherwise.
pub fn central_difference(x: &[f64], dof: usize, h: f64, periodic: bool) -> Vec<f64> {
    let n = x.len() / dof;
    let mut d = vec![0.0; x.len()];
    for k in 0..n {
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
fn filter_columns(filter: &Butterworth, x: &[f64], dof: usize, periodic: bool) -> Result<Vec<f64>, FilterError> {
    let mut out = vec![0.0; x.len()];
    match periodic {
        true => filter.filtfilt_rows_periodic(x, dof, &mut out)?,
        false => filter.filtfilt_rows(x, dof, &mut out)?,
    }
    Ok(out)
}

/// The cut-off for a log of a known trajectory whose highest frequency is `bandwidth_hz`: five
/// times it, at least 1 Hz. Closed-loop positions carry controller dither that fools a cut-off
/// read off their spectrum ([`default_cutoff_hz`]), so a log that names its trajectory uses this.
pub fn cutoff_for_bandwidth(bandwidth_hz: f64) -> f64 {
    (CUTOFF_PER_BANDWIDTH * bandwidth_hz).max(MIN_CUTOFF_HZ)
}

/// The cut-off over the highest frequency of the trajectory: the filter then passes the
/// trajectory's harmonics with a phase-free (forward–backward) gain near one.
pub const CUTOFF_PER_BANDWIDTH: f64 = 5.0;

/// The lowest cut-off either rule gives (Hz).
pub const MIN_CUTOFF_HZ: f64 = 1.0;

/// Cut-off from the trajectory's bandwidth: five times the highest frequency that carries at least
/// 0.1 % of the largest spectral amplitude of any joint's position, kept within [1 Hz, fs/4].
///
/// For a periodic average the spectrum is taken at the period's harmonics; otherwise at 200
/// logarithmically spaced frequencies from 0.05 Hz to fs/4 (a direct DFT on at most ~20,000
/// evenly strided samples).
pub fn default_cutoff_hz(q: &[f64], dof: usize, fs: f64, periodic: bool) -> f64 {
    let n = q.len() / dof;
    let duration = n as f64 / fs;
    let frequencies: Vec<f64> = if periodic {
        (1..=(n / 2).min(400)).map(|k| k as f64 / duration).collect()
    } else {
        let (lo, hi) = (0.05f64.max(2.0 / duration), fs / 4.0);
        (0..200).map(|i| lo * (hi / lo).powf(i as f64 / 199.0)).collect()
    };
    let stride = if periodic { 1 } else { (n / 20_000).max(1) };
    let mut highest = 0.0_f64;
    let mut spectrum = vec![0.0; frequencies.len()];
    for j in 0..dof {
        let column: Vec<f64> = q.iter().skip(j).step_by(dof).step_by(stride).copied().collect();
        let mean = column.iter().sum::<f64>() / column.len() as f64;
        let dt = stride as f64 / fs;
        for (s, f) in spectrum.iter_mut().zip(&frequencies) {
            let w = 2.0 * std::f64::consts::PI * f * dt;
            let (mut re, mut im) = (0.0, 0.0);
            for (k, v) in column.iter().enumerate() {
                let (sin, cos) = (w * k as f64).sin_cos();
                re += (v - mean) * cos;
                im -= (v - mean) * sin;
            }
            *s = (re * re + im * im).sqrt();
        }
        let peak = spectrum.iter().copied().fold(0.0, f64::max);
        if let Some(i) = spectrum.iter().rposition(|s| *s >= 1e-3 * peak && peak > 0.0) {
            highest = highest.max(frequencies[i]);
        }
    }
    (CUTOFF_PER_BANDWIDTH * highest).clamp(MIN_CUTOFF_HZ, fs / 4.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three joints, sum of harmonics of a 15 s period, sampled at 1 kHz.
    fn periodic_log(periods: usize, noise: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let (fs, period) = (1000.0, 15.0);
        let n = (fs * period) as usize * periods;
        let w = 2.0 * std::f64::consts::PI / period;
        let mut state = 12345u64;
        let mut noise_sample = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * noise
        };
        let t: Vec<f64> = (0..n).map(|i| i as f64 / fs).collect();
        let mut q = Vec::with_capacity(3 * n);
        let mut tau = Vec::with_capacity(3 * n);
        for &ti in &t {
            for j in 0..3 {
                let a = 0.3 * (w * ti + j as f64).sin() + 0.1 * (3.0 * w * ti).cos();
                q.push(a + noise_sample());
                tau.push(2.0 * a + noise_sample());
            }
        }
        (t, q, tau)
    }

    /// Worst error of q̇ and q̈ after preprocessing, relative to their amplitudes.
    fn derivative_error(noise: f64) -> f64 {
        let (t, q, tau) = periodic_log(4, noise);
        let options = PreprocessOptions { periods: Some(4), ..Default::default() };
        let out = preprocess(&t, &q, &tau, 3, &options).unwrap();
        assert_eq!(out.samples(), 15_000);
        assert_eq!(out.periods_averaged, 4);
        let w = 2.0 * std::f64::consts::PI / 15.0;
        // Highest harmonic 3w/2π = 0.2 Hz, so the bandwidth rule gives 1 Hz (its floor).
        assert!((out.cutoff_hz - 1.0).abs() < 1e-12, "cut-off {}", out.cutoff_hz);
        let mut worst: f64 = 0.0;
        for (k, &ti) in out.t.iter().enumerate() {
            for j in 0..3 {
                let qd = 0.3 * w * (w * ti + j as f64).cos() - 0.3 * w * (3.0 * w * ti).sin();
                let qdd = -0.3 * w * w * (w * ti + j as f64).sin() - 0.9 * w * w * (3.0 * w * ti).cos();
                worst = worst.max((out.qd[k * 3 + j] - qd).abs() / 0.1).max((out.qdd[k * 3 + j] - qdd).abs() / 0.05);
            }
        }
        worst
    }

    #[test]
    fn periodic_pipeline_recovers_derivatives_of_a_known_signal() {
        // Noise-free: only filter attenuation and the O(h²) difference error remain.
        let clean = derivative_error(0.0);
        assert!(clean < 1e-5, "relative derivative error {clean}");
        // Encoder-sized noise (±0.1 mrad) survives two differentiations only attenuated.
        let noisy = derivative_error(1e-4);
        assert!(noisy < 5e-3, "relative derivative error with noise {noisy}");
    }

    #[test]
    fn bad_logs_are_refused_by_name() {
        let (t, q, tau) = periodic_log(2, 0.0);
        let err = |r: Result<Preprocessed, PreprocessError>| r.unwrap_err().to_string();
        let opts = PreprocessOptions::default();
        assert!(err(preprocess(&t, &q[..q.len() - 3], &tau, 3, &opts)).contains("q has"));
        let mut bad = q.clone();
        bad[300] = f64::NAN;
        assert!(err(preprocess(&t, &bad, &tau, 3, &opts)).contains("q is not finite at sample 100"));
        let mut jumpy = t.clone();
        jumpy[500..].iter_mut().for_each(|x| *x += 0.01);
        assert!(err(preprocess(&jumpy, &q, &tau, 3, &opts)).contains("step 499"));
        let one = PreprocessOptions { periods: Some(1), ..Default::default() };
        assert!(err(preprocess(&t, &q, &tau, 3, &one)).contains("at least 2 whole periods"));
    }
}
