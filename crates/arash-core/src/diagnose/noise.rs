//! The held-out torque's noise floor: the part of its error in the band that no model of the
//! motion can explain, and the held-out gain judged against the error above it.
//!
//! A current-sensed torque at 100–500 Hz carries noise of several per cent of its RMS, and in a
//! wide band that noise is a large share of the declared model's held-out error. An effect that
//! removes half of what the model misses then cuts the held-out error by much less than half, and
//! a fixed bar (`min_gain`) set against all of it measures the sensor as much as the effect. So
//! each joint's torque noise is estimated from the data ([`white_noise_variance`]), carried into
//! the band, and a gain is the share of the error *above* it that an effect removes, as far as
//! the error stands clear of it by its sampling error ([`NoiseFloor::gains`]).
//!
//! The band is the widest in which the declared model predicts held-out torque as well as in the
//! best (`band_choice.rs`). What it holds above the narrowest such band adds nothing the declared
//! model predicts: content of the torque no model of the motion explains (a drive's current
//! ripple, a servo's own dynamics), which would dilute every gain as the sensor's noise does. So
//! the floor is also at least the held-out error the band adds above that narrowest band
//! ([`NoiseFloor::above`]).

use super::band::white_noise_gain;
use crate::signal::conditioning::filter_columns;
use crate::signal::filter::{Butterworth, FilterError};

/// The noise is read above this share of the sample rate: a robot's motion and what the declared
/// model explains lie far below it, and the torque holds only noise there, besides the friction's
/// steps at reversals, which are rare and which the median ignores.
const NOISE_FROM_SHARE: f64 = 0.25;

/// The scale of a normal distribution's median absolute deviation: σ = 1.4826 · MAD.
const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

/// The floor is subtracted from the error a gain is judged against in proportion to how clearly
/// the error stands above it: the share 1 − (FLOOR_CLEAR_SIGMAS / z)², none below, z the error
/// above the floor in its own standard errors ([`NoiseFloor::gains`]). Within two standard errors
/// of the floor a model has nothing left it can be shown to miss, and a share of almost nothing is
/// no measure, so the gain is judged against the whole error; far clear of it, against the error
/// above it; between, continuously (the positive-part James–Stein factor). A floor counted all or
/// nothing at two standard errors made every gain of a joint jump several-fold when the error
/// moved by a fraction of one (docs/diagnosis.md, "The noise floor").
pub const FLOOR_CLEAR_SIGMAS: f64 = 2.0;

/// Each joint's white-noise variance of an unfiltered torque `tau` (`N × dof`, row-major, at
/// `fs`), from the median absolute deviation of its content above [`NOISE_FROM_SHARE`] of the
/// sample rate, scaled back to all frequencies by the share of a white noise's variance that
/// content holds.
pub fn white_noise_variance(tau: &[f64], dof: usize, fs: f64, order: usize) -> Result<Vec<f64>, FilterError> {
    let filter = Butterworth::lowpass(order, NOISE_FROM_SHARE * fs, fs)?;
    let low = filter_columns(&filter, tau, dof, false)?;
    // The share of a unit white noise's variance above the cut-off: Σ (δ − h)², h the
    // zero-phase impulse response.
    let n = 2 * filter.padlen() + 401;
    let mut impulse = vec![0.0; n];
    impulse[n / 2] = 1.0;
    let h = filter_columns(&filter, &impulse, 1, false)?;
    let high_share: f64 = impulse.iter().zip(&h).map(|(d, h)| (d - h).powi(2)).sum();
    let samples = tau.len() / dof.max(1);
    Ok((0..dof)
        .map(|k| {
            let high: Vec<f64> = (0..samples).map(|s| tau[s * dof + k] - low[s * dof + k]).collect();
            let sigma = MAD_TO_SIGMA * median_absolute_deviation(high);
            sigma * sigma / high_share
        })
        .collect())
}

fn median_absolute_deviation(mut x: Vec<f64>) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mid = x.len() / 2;
    let median = *x.select_nth_unstable_by(mid, f64::total_cmp).1;
    x.iter_mut().for_each(|v| *v = (*v - median).abs());
    *x.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The noise floor of a held-out set, per joint, in the diagnosis's weighted units.
#[derive(Clone, Debug)]
pub(super) struct NoiseFloor {
    /// The squared error no model of the motion removes from the held-out samples, per joint
    /// (weighted).
    pub(super) sse: Vec<f64>,
    /// Its RMS per joint (N·m or N): what the report gives.
    pub(super) rms: Vec<f64>,
    /// The torque's white noise in the band, RMS per joint (N·m or N).
    pub(super) noise_rms: Vec<f64>,
    /// Held-out samples, and the weights that made the squared errors.
    samples: usize,
    weights: Vec<f64>,
    /// Independent samples the held-out error is summed over (the band's 2·c per second).
    independent: f64,
}

/// The held-out torque a noise floor is measured on: its unfiltered samples (`N × dof` at `fs`),
/// the filter's `order` and `cutoff_hz`, the joints' row weights, and how many held-out samples
/// the error is summed over, spanning `duration_s`.
pub(super) struct HeldOutTorque<'a> {
    pub tau: &'a [f64],
    pub dof: usize,
    pub fs: f64,
    pub order: usize,
    pub cutoff_hz: f64,
    pub weights: &'a [f64],
    pub samples: usize,
    pub duration_s: f64,
}

impl NoiseFloor {
    /// The floor of the held-out samples `held` describes.
    pub(super) fn of(held: HeldOutTorque) -> Result<Self, FilterError> {
        let HeldOutTorque { tau, dof, fs, order, cutoff_hz, weights, samples, duration_s } = held;
        let variance = white_noise_variance(tau, dof, fs, order)?;
        let in_band = white_noise_gain(fs, cutoff_hz, order, 0)?;
        let rms: Vec<f64> = variance.iter().map(|v| (v * in_band).sqrt()).collect();
        let sse = rms.iter().zip(weights).map(|(r, w)| samples as f64 * (r * w).powi(2)).collect();
        let independent = (2.0 * cutoff_hz * duration_s).max(1.0);
        Ok(Self { sse, noise_rms: rms.clone(), rms, samples, weights: weights.to_vec(), independent })
    }

    /// No floor (every gain against the whole error).
    pub(super) fn none(dof: usize) -> Self {
        let zeros = vec![0.0; dof];
        Self {
            sse: zeros.clone(),
            rms: zeros.clone(),
            noise_rms: zeros,
            samples: 0,
            weights: vec![1.0; dof],
            independent: 1.0,
        }
    }

    /// This floor raised, joint by joint, to the held-out error the band adds above the narrowest
    /// one that predicts as well: `before` is the declared model's held-out squared error here,
    /// `narrowest` that band's (its own squared errors over its own held-out samples, and its
    /// white-noise floor), compared per held-out sample.
    pub(super) fn above(mut self, before: &[f64], narrowest: &[f64], at_narrowest: &NoiseFloor) -> Self {
        let per = |sse: f64, n: usize| sse / n.max(1) as f64;
        for k in 0..self.sse.len() {
            let explainable =
                (per(narrowest[k], at_narrowest.samples) - per(at_narrowest.sse[k], at_narrowest.samples)).max(0.0);
            let added = before[k] - explainable * self.samples as f64;
            self.sse[k] = self.sse[k].max(added);
            self.rms[k] = (per(self.sse[k], self.samples)).sqrt() / self.weights[k];
        }
        self
    }

    /// Per joint, the relative cut of the held-out squared error from `before` to `after`, over
    /// the error less the share of the floor that [`FLOOR_CLEAR_SIGMAS`] gives (a sum of squares
    /// over `independent` samples has a relative standard error of √(2/independent)). A cut beyond
    /// that (where an effect's own content reaches above the narrowest band) is all of it: 1.
    pub(super) fn gains(&self, before: &[f64], after: &[f64]) -> Vec<f64> {
        let relative_error = (2.0 / self.independent).sqrt();
        before
            .iter()
            .zip(after)
            .zip(&self.sse)
            .map(|((b, a), floor)| {
                let clear = (b - floor) / (relative_error * b);
                let trusted = match clear > FLOOR_CLEAR_SIGMAS {
                    true => 1.0 - (FLOOR_CLEAR_SIGMAS / clear).powi(2),
                    false => 0.0,
                };
                let denominator = b - trusted * floor;
                if denominator > 0.0 {
                    ((b - a) / denominator).min(1.0)
                } else {
                    0.0
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// White noise of known σ on two joints, under a slow motion and a friction step at every
    /// reversal: the estimate finds σ², whatever the motion.
    #[test]
    fn the_white_noise_of_a_torque_is_read_under_its_motion_and_steps() {
        let (fs, n) = (200.0, 20_000);
        let sigma = [0.05, 2.0];
        // A Gaussian-like noise from the sum of twelve uniforms (variance 1), reproducible.
        let mut state = 12345u64;
        let mut uniform = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut tau = vec![0.0; 2 * n];
        for s in 0..n {
            let t = s as f64 / fs;
            let motion = (std::f64::consts::TAU * 0.4 * t).sin();
            for k in 0..2 {
                let noise: f64 = (0..12).map(|_| uniform()).sum::<f64>() - 6.0;
                let scale = [1.0, 40.0][k];
                tau[2 * s + k] = scale * (motion + 0.3 * motion.signum()) + sigma[k] * noise;
            }
        }
        let v = white_noise_variance(&tau, 2, fs, 5).unwrap();
        for k in 0..2 {
            assert!((v[k].sqrt() / sigma[k] - 1.0).abs() < 0.05, "joint {k}: {} against {}", v[k].sqrt(), sigma[k]);
        }
    }

    /// A cut judged against the error less the floor's trusted share: nearly all the floor where
    /// the error stands far clear of it, none within two standard errors, and a gain that moves
    /// continuously as the error crosses two standard errors (no jump).
    #[test]
    fn a_gain_is_judged_above_the_floor_as_far_as_the_error_stands_clear_of_it() {
        let mut floor = NoiseFloor::none(3);
        floor.sse = vec![60.0, 99.0, 0.0];
        floor.independent = 1000.0;
        let se = (2.0f64 / 1000.0).sqrt() * 100.0;
        let g = floor.gains(&[100.0, 100.0, 100.0], &[80.0, 99.5, 90.0]);
        // Joint 0: 40 above the floor, z = 40/se; the floor's trusted share 1 − (2/z)².
        let share = 1.0 - (2.0 * se / 40.0f64).powi(2);
        assert!((g[0] - 20.0 / (100.0 - share * 60.0)).abs() < 1e-12, "{g:?}");
        assert!(g[0] > 0.45 && g[0] < 0.5, "{g:?}");
        // Joint 1: 1 above, well within two standard errors: the whole error.
        assert!((g[1] - 0.005).abs() < 1e-12, "{g:?}");
        // Joint 2: no floor at all.
        assert!((g[2] - 0.1).abs() < 1e-12, "{g:?}");
        // Across two standard errors the gain moves by no more than the error does.
        let at = |above: f64| {
            let mut f = NoiseFloor::none(1);
            f.sse = vec![100.0 - above];
            f.independent = 1000.0;
            f.gains(&[100.0], &[99.0])[0]
        };
        let (below, above) = (at(2.0 * se - 1e-6), at(2.0 * se + 1e-6));
        assert!((above - below).abs() < 1e-6, "{below} against {above}");
    }
}
