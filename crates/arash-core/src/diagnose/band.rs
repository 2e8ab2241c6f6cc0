//! What the band's choice reads from a log's positions, and the friction velocity's cut-off.
//!
//! The diagnosis's band itself is chosen by how well the declared model predicts held-out torque
//! (`band_choice.rs`). The friction columns then switch with the velocity filtered at that band,
//! or slower where a coarse encoder's steps would make it pulse around each reversal
//! ([`velocity_resolved_cutoff`]): where the positions are whole multiples of an encoder step,
//! the quantisation's share of the velocity is known (Δ²/12, white, through the filter and the
//! difference).

use super::options::MAX_VELOCITY_NOISE;
use crate::choices::Choice;
use crate::signal::conditioning::{central_difference, filter_columns};
use crate::signal::data_choices::bandwidth;
use crate::signal::encoder::encoder_step;
use crate::signal::filter::{Butterworth, FilterError};
use crate::signal::preprocess::{lowest_cutoff_hz, CUTOFF_PER_BANDWIDTH, EDGE_CUTOFF_PERIODS};

/// The band the training log was filtered in, which a validation log is filtered in too.
#[derive(Clone, Copy, Debug)]
pub(super) struct Band {
    pub(super) cutoff_hz: f64,
    pub(super) friction_hz: f64,
}

/// Cut-offs tried per halving, from the top down.
const STEPS_PER_OCTAVE: i32 = 4;

/// A friction velocity's cut-off and why.
pub(super) struct Chosen {
    pub(super) cutoff_hz: f64,
    pub(super) reason: Choice,
}

/// What the band's choice reads from a log's positions, once: each joint's encoder step
/// ([`encoder_step`]), the motion's bandwidth, and the lowest cut-off the friction velocity may
/// have ([`CUTOFF_PER_BANDWIDTH`] times the bandwidth, and what the log's length allows).
pub(super) struct Positions<'a> {
    q: &'a [f64],
    dof: usize,
    pub(super) fs: f64,
    steps: Vec<Option<f64>>,
    floor: f64,
    /// The motion's bandwidth read from the positions' spectrum (Hz), if any joint moves.
    pub(super) bandwidth_hz: Option<f64>,
}

impl<'a> Positions<'a> {
    pub(super) fn of(q: &'a [f64], dof: usize, fs: f64) -> Self {
        let length = lowest_cutoff_hz(q.len() / dof, fs, false);
        let bandwidth_hz = bandwidth(q, dof, fs, false);
        let floor = bandwidth_hz.map_or(0.0, |b| CUTOFF_PER_BANDWIDTH * b).max(length);
        Self { q, dof, fs, steps: (0..dof).map(|j| encoder_step(q, dof, j)).collect(), floor, bandwidth_hz }
    }
}

/// The friction velocity's cut-off: the widest, from the band's `cutoff` down in quarter
/// octaves, at which every joint's encoder step reaches the filtered velocity with an RMS of at
/// most [`MAX_VELOCITY_NOISE`] of the joint's RMS speed, never below what the motion needs.
///
/// The friction columns switch and decay with this velocity near zero speed, where a coarse
/// encoder's position stays put for many samples and then steps: at the band's cut-off that
/// staircase makes the velocity pulse around each reversal, and a Stribeck column built on it
/// mostly fits the pulses (issue 19: Stribeck friction at 15 % of the insertion's torque, 12-bit
/// encoders at 200 Hz, was missed on 2 of 10 logs, found on all ten with the velocity at 4 Hz).
/// Joints whose positions show no step (filtered, or smooth real data) leave the band alone:
/// what their velocity gains is motion.
pub(super) fn velocity_resolved_cutoff(
    positions: &Positions,
    cutoff: f64,
    order: usize,
) -> Result<Chosen, FilterError> {
    if positions.steps.iter().all(Option::is_none) {
        let reason = Choice::FrictionAtBandNoGrid { cutoff_hz: cutoff };
        return Ok(Chosen { cutoff_hz: cutoff, reason });
    }
    let floor = positions.floor.min(cutoff);
    let limit = MAX_VELOCITY_NOISE;
    let mut at_band: Option<NoiseShare> = None;
    let mut candidate = cutoff;
    loop {
        let share = velocity_noise(positions, candidate, order)?;
        let first = *at_band.get_or_insert(share);
        let narrower = candidate * 0.5_f64.powf(1.0 / STEPS_PER_OCTAVE as f64);
        if share.value <= MAX_VELOCITY_NOISE || narrower < floor {
            let (cutoff_hz, joint, share) = (candidate, share.joint, share.value);
            let reason = match (candidate == cutoff, share <= MAX_VELOCITY_NOISE) {
                (true, _) => Choice::FrictionAtBand { cutoff_hz, joint, share, limit },
                (false, true) => Choice::FrictionNarrowed {
                    cutoff_hz,
                    band_hz: cutoff,
                    band_joint: first.joint,
                    band_share: first.value,
                    joint,
                    share,
                    limit,
                },
                (false, false) => Choice::FrictionLowest { cutoff_hz, joint, share, limit },
            };
            return Ok(Chosen { cutoff_hz: candidate, reason });
        }
        candidate = narrower;
    }
}

/// The largest share of a joint's RMS speed that its encoder step's quantisation makes up in
/// the velocity filtered at `cutoff` (the step's Δ²/12, white, through the filter and one central
/// difference), over the joints that show a step.
fn velocity_noise(positions: &Positions, cutoff: f64, order: usize) -> Result<NoiseShare, FilterError> {
    let Positions { q, dof, fs, ref steps, .. } = *positions;
    let mut worst = NoiseShare { joint: 0, value: 0.0 };
    let n = q.len() / dof;
    let edge = ((EDGE_CUTOFF_PERIODS * fs / cutoff).ceil() as usize).min(n / 4);
    let gain = white_noise_gain(fs, cutoff, order, 1)?;
    let v = differenced(q, dof, fs, cutoff, order, 1)?;
    for (j, step) in steps.iter().enumerate().filter_map(|(j, s)| s.map(|s| (j, s))) {
        let speed = (edge..n - edge).map(|k| v[k * dof + j].powi(2)).sum::<f64>() / (n - 2 * edge).max(1) as f64;
        let noise = step * step / 12.0 * gain;
        if speed > 0.0 && (noise / speed).sqrt() > worst.value {
            worst = NoiseShare { joint: j, value: (noise / speed).sqrt() };
        }
    }
    Ok(worst)
}

/// The largest share of a joint's q̈ variance that position noise makes up at a cut-off.
#[derive(Clone, Copy, Debug)]
struct NoiseShare {
    joint: usize,
    value: f64,
}

/// q̇ (`times` = 1) or q̈ (2) as the diagnosis computes them: the position filtered at `cutoff`,
/// central-differenced `times` times.
fn differenced(
    q: &[f64],
    dof: usize,
    fs: f64,
    cutoff: f64,
    order: usize,
    times: usize,
) -> Result<Vec<f64>, FilterError> {
    let mut x = filter_columns(&Butterworth::lowpass(order, cutoff, fs)?, q, dof, false)?;
    for _ in 0..times {
        x = central_difference(&x, dof, 1.0 / fs, false);
    }
    Ok(x)
}

/// The variance the position filtered at `cutoff` (`times` = 0), q̇ (1) or q̈ (2) gets from unit
/// white noise on the position: the sum of
/// squares of the impulse response of the filter at `cutoff` and the central differences.
pub(super) fn white_noise_gain(fs: f64, cutoff: f64, order: usize, times: usize) -> Result<f64, FilterError> {
    let filter = Butterworth::lowpass(order, cutoff, fs)?;
    let n = 2 * filter.padlen() + (40.0 * fs / cutoff).ceil() as usize;
    let mut impulse = vec![0.0; n];
    impulse[n / 2] = 1.0;
    let response = differenced(&impulse, 1, fs, cutoff, order, times)?;
    Ok(response.iter().map(|r| r * r).sum())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_4, PI, TAU};

    /// Positions on the grid of a `bits` encoder (a turn, or 0.1 m for the insertion).
    fn quantum(joint: usize, bits: u32) -> f64 {
        [TAU, TAU, 0.1][joint] / 2f64.powi(bits as i32)
    }

    /// Three joints (two rotations and an insertion, as ARASH:ASiST's) moving in two tones each at
    /// `fs` for `seconds`, plus `dither` (a share of the amplitude) at 12 Hz, read through `bits`
    /// encoders.
    fn rig_log(fs: f64, seconds: f64, bits: u32, dither: f64) -> Vec<f64> {
        let (amplitude, n) = ([0.3, 0.2, 0.02], (fs * seconds) as usize);
        let mut q = vec![0.0; 3 * n];
        for k in 0..n {
            let t = k as f64 / fs;
            for j in 0..3 {
                let (a, w1, w2, w3) = (amplitude[j], TAU * 0.3, TAU * 0.9, TAU * 12.0);
                let x = a * (w1 * t).sin() + 0.2 * a * (w2 * t).cos() + dither * a * (w3 * t).sin();
                q[3 * k + j] = (x / quantum(j, bits)).round() * quantum(j, bits);
            }
        }
        q
    }

    /// The quantisation noise reaching the velocity at c is Δ²/12 · (2/fs) · (2π)² c³ · 0.07π /
    /// sin(0.3π) (see the gain's test): the friction velocity keeps it under the limit of the
    /// worst joint's RMS speed, and the next wider step does not; a fine encoder keeps the band.
    #[test]
    fn a_coarse_encoder_slows_the_friction_velocity_where_the_noise_formula_says() {
        let (fs, bits) = (200.0, 14);
        let q = rig_log(fs, 60.0, bits, 0.0);
        let band = 20.0;
        let Chosen { cutoff_hz: friction, reason, .. } =
            velocity_resolved_cutoff(&Positions::of(&q, 3, fs), band, 5).unwrap();
        let amplitude = [0.3, 0.2, 0.02];
        let share = |c: f64| {
            (0..3)
                .map(|j| {
                    let d = quantum(j, bits);
                    let noise = d * d / 12.0 * (2.0 / fs) * TAU.powi(2) * c.powi(3) * 0.07 * PI / (0.3 * PI).sin();
                    let speed =
                        0.5 * (amplitude[j] * TAU * 0.3).powi(2) + 0.5 * (0.2 * amplitude[j] * TAU * 0.9).powi(2);
                    (noise / speed).sqrt()
                })
                .fold(0.0, f64::max)
        };
        let wider = friction * 2f64.powf(0.25);
        assert!(friction < band, "{reason}");
        assert!(share(friction) < 1.2 * MAX_VELOCITY_NOISE, "{friction} Hz: {}", share(friction));
        assert!(share(wider) > 0.8 * MAX_VELOCITY_NOISE, "{wider} Hz: {}", share(wider));
        // 12 bits would need a velocity slower than the motion allows: it stops there, and says so.
        let coarse = velocity_resolved_cutoff(&Positions::of(&rig_log(fs, 60.0, 12, 0.0), 3, fs), band, 5).unwrap();
        assert!(
            coarse.cutoff_hz < friction && matches!(coarse.reason, Choice::FrictionLowest { .. }),
            "{}",
            coarse.reason
        );
        let fine = rig_log(fs, 60.0, 20, 0.0);
        let kept = velocity_resolved_cutoff(&Positions::of(&fine, 3, fs), band, 5).unwrap();
        assert_eq!(kept.cutoff_hz, band, "{}", kept.reason);
        // Positions on no grid (filtered, or a smooth real log): no step to blame, the band stays.
        let smooth: Vec<f64> = q.iter().enumerate().map(|(k, x)| x + 1e-7 * (0.1234 * k as f64).sin()).collect();
        let unstepped = velocity_resolved_cutoff(&Positions::of(&smooth, 3, fs), band, 5).unwrap();
        assert!(
            unstepped.cutoff_hz == band && matches!(unstepped.reason, Choice::FrictionAtBandNoGrid { .. }),
            "{}",
            unstepped.reason
        );
    }

    /// A daemon log resampled where its time stamps jittered holds a few positions between the
    /// steps (`flightlog::on_uniform_grid`): the step is still read from all the others.
    #[test]
    fn a_few_interpolated_positions_do_not_hide_the_encoder_step() {
        let mut q = rig_log(1000.0, 20.0, 16, 0.0);
        let samples = q.len() / 3;
        for i in (1..samples - 1).step_by(250) {
            for j in 0..3 {
                q[3 * i + j] = 0.3 * q[3 * (i - 1) + j] + 0.7 * q[3 * (i + 1) + j];
            }
        }
        for j in 0..3 {
            let step = encoder_step(&q, 3, j).expect("the step shows through 0.4 % interpolated samples");
            assert!((step / quantum(j, 16) - 1.0).abs() < 1e-9, "joint {j}: {step}");
        }
    }

    #[test]
    fn the_encoder_step_is_read_from_the_positions() {
        let q = rig_log(1000.0, 5.0, 12, 0.0);
        for j in 0..3 {
            let step = encoder_step(&q, 3, j).unwrap();
            assert!((step / quantum(j, 12) - 1.0).abs() < 1e-9, "{step}");
        }
        let smooth: Vec<f64> = (0..1000).map(|k| (k as f64 * 0.01).sin()).collect();
        assert_eq!(encoder_step(&smooth, 1, 0), None);
    }

    /// The gain against its closed form: white noise of unit variance has the one-sided density
    /// 2/fs, two differences multiply it by (2πf)⁴ (less a droop of 1 % at 20 Hz of 1 kHz), and
    /// an order-n Butterworth run forward and backward by 1/(1 + (f/c)^2n)², whose integral
    /// against f⁴ is c⁵/5 · π/4 for n = 5.
    #[test]
    fn the_white_noise_gain_is_close_to_the_ideal_low_pass() {
        let (fs, c) = (1000.0, 20.0_f64);
        let exact = 2.0 / fs * TAU.powi(4) * c.powi(5) / 5.0 * FRAC_PI_4;
        let gain = white_noise_gain(fs, c, 5, 2).unwrap();
        assert!((gain / exact - 1.0).abs() < 0.02, "{gain} against {exact}");
    }

    /// The same for the velocity: one difference multiplies the density by (2πf)², and the
    /// integral of f² against the filter is c³ · Γ(0.3)Γ(1.7)/10 = c³ · 0.07π / sin(0.3π).
    #[test]
    fn the_velocitys_white_noise_gain_is_close_to_the_ideal_low_pass() {
        let (fs, c) = (1000.0, 20.0_f64);
        let exact = 2.0 / fs * TAU.powi(2) * c.powi(3) * 0.07 * PI / (0.3 * PI).sin();
        let gain = white_noise_gain(fs, c, 5, 1).unwrap();
        assert!((gain / exact - 1.0).abs() < 0.02, "{gain} against {exact}");
    }
}
