//! The samples at which a joint rests, which identification leaves out of its equations.
//!
//! A joint held still by dry friction feels whatever friction holds it, anywhere between the
//! Coulomb bounds: at those samples its friction is not a law of its velocity, neither sign(q̇)
//! nor a smooth one, and a row that states one biases every column that correlates with the
//! stops. Under a sign law in closed loop the insertion of ARASH:ASiST rested at 27 % of the
//! samples, and least squares with those rows validated at 77 / 98 / 81 % on the paper's
//! trajectories; left out, 99 % on every joint (docs/identification.md, "A sign-law closed loop").
//! Leaving a resting joint's rows out is the maximum-likelihood treatment of the set-valued law:
//! its friction there is an unknown bounded by f_c, which takes up that row exactly.
//!
//! A rest is read from the raw encoder: a reading that holds for at least [`REST_HOLD_S`].

use crate::choices::Choice;
use crate::signal::conditioning::Averaging;
use crate::signal::encoder::encoder_step;

/// A joint rests where its reading holds for at least this long (s). A reading repeated for a
/// sample or two is slow motion across one encoder step; under closed-loop control a joint held by
/// its friction stays for tens to hundreds of milliseconds while the loop's torque builds (the
/// sign-law closed loop's insertion held for 10 ms or more at 38 % of the samples). Any hold from 3
/// to 50 ms left out gave the same validation there (98–99.8 % on every joint); longer holds let
/// the short stops bias the fit (docs/identification.md).
pub const REST_HOLD_S: f64 = 0.01;

/// Samples a reading must hold at `dt` for a rest: [`REST_HOLD_S`], and never fewer than four.
/// Below 400 Hz 10 ms is three samples or fewer, and a reading repeated for a sample or two is a
/// slow joint crossing one encoder step: at 200 Hz (two samples) the generator's KUKA (sign law,
/// 16-bit) lost the samples near its reversals, which tell sign(q̇) from a smooth law, and seed 7
/// chose tanh(q̇/0.51) on joint 1 and fitted at 92.4 % mean FP% (99.5 % with four).
pub fn hold_samples(dt: f64) -> usize {
    ((REST_HOLD_S / dt).ceil() as usize).max(4)
}

/// Which samples of the raw log `q` (`N × dof`) lie within a run of identical readings at least
/// `hold` samples long, joint by joint (`N × dof`).
pub fn resting_in_log(q: &[f64], dof: usize, hold: usize) -> Vec<bool> {
    let n = q.len() / dof.max(1);
    let mut resting = vec![false; n * dof];
    // Row by row, every joint's run at once: the log is read once, in order.
    let mut start = vec![0; dof];
    for i in 1..=n {
        for (k, first) in start.iter_mut().enumerate() {
            if i == n || q[i * dof + k] != q[*first * dof + k] {
                if i - *first >= hold {
                    (*first..i).for_each(|s| resting[s * dof + k] = true);
                }
                *first = i;
            }
        }
    }
    resting
}

/// Encoder steps a joint can travel without its reading changing: to the edge of its step and
/// back. A friction velocity that travels further over a run of identical readings is not the
/// joint's motion.
pub const STOP_TRAVEL_STEPS: f64 = 2.0;

/// Which samples of the raw log `q` (`N × dof`, step `dt`) lie in or within `widen` samples of a
/// *stop*: a run of identical readings, of any length, over which the joint's friction velocity
/// `velocity` (the same layout, filtered at the friction velocity's cut-off) travels more than
/// [`STOP_TRAVEL_STEPS`] of its encoder's step. Joints whose positions are not an encoder's
/// ([`encoder_step`]) have none.
///
/// Under a set-valued friction a joint stops at most reversals for less than a rest: its
/// friction there ramps with the controller's torque, while a friction velocity filtered at a
/// few hertz passes slowly through zero, and a smooth law of that velocity fits the ramp better
/// than `sign(q̇)` (docs/identification.md, "Fresh seeds, and a second loop"). `widen` is the
/// filters' memory: a filtered sample that near a stop holds some of it.
pub fn stopped_in_log(q: &[f64], velocity: &[f64], dof: usize, dt: f64, widen: usize) -> Vec<bool> {
    let n = q.len() / dof.max(1);
    let mut stopped = vec![false; n * dof];
    for k in 0..dof {
        let Some(step) = encoder_step(q, dof, k) else { continue };
        let mut first = 0;
        let mut travel = 0.0;
        for i in 1..=n {
            if i == n || q[i * dof + k] != q[first * dof + k] {
                if travel > STOP_TRAVEL_STEPS * step {
                    let (from, to) = (first.saturating_sub(widen), (i + widen).min(n));
                    (from..to).for_each(|s| stopped[s * dof + k] = true);
                }
                first = i;
                travel = 0.0;
            } else {
                // The reading held from sample i − 1 to i: the velocity's travel over that step.
                travel += 0.5 * (velocity[(i - 1) * dof + k].abs() + velocity[i * dof + k].abs()) * dt;
            }
        }
    }
    stopped
}

/// [`resting_in_log`] arranged as the preprocessed samples are ([`arrange`]).
pub fn resting(q: &[f64], dof: usize, averaging: Option<Averaging>, dt: f64, decimate: usize) -> Vec<bool> {
    arrange(resting_in_log(q, dof, hold_samples(dt)), dof, averaging, decimate)
}

/// Flags of the raw log (`N × dof`) arranged as the preprocessed samples are: with `averaging`, a
/// sample of the averaged period is flagged where the joint is flagged in any of the periods (the
/// averaged torque holds that period's holding friction); then every `decimate`-th sample.
pub fn arrange(raw: Vec<bool>, dof: usize, averaging: Option<Averaging>, decimate: usize) -> Vec<bool> {
    let arranged = match averaging {
        None => raw,
        // A period of whole samples: each period's own samples, or-ed slice by slice.
        Some(a) if a.samples == a.per() as f64 => {
            let mut any = vec![false; a.per() * dof];
            for period in raw.chunks_exact(any.len()).take(a.count) {
                any.iter_mut().zip(period).for_each(|(r, p)| *r |= *p);
            }
            any
        }
        Some(a) => {
            let n = raw.len() / dof.max(1);
            let per = a.per();
            let step = a.samples / per as f64;
            let mut any = vec![false; per * dof];
            for p in 0..a.count {
                for i in 0..per {
                    let position = p as f64 * a.samples + i as f64 * step;
                    // A resampled point rests where either raw sample around it does.
                    let (below, above) = (position.floor() as usize, position.ceil() as usize);
                    for k in 0..dof {
                        let at = |s: usize| s < n && raw[s * dof + k];
                        any[i * dof + k] |= at(below) || at(above);
                    }
                }
            }
            any
        }
    };
    arranged.chunks(dof.max(1)).step_by(decimate.max(1)).flatten().copied().collect()
}

/// The reason: each joint's share of resting samples among `samples` (indices of `resting`,
/// `samples × dof`), when any joint rests.
pub fn explain(resting: &[bool], dof: usize, samples: std::ops::Range<usize>, dt: f64) -> Option<Choice> {
    let count = samples.len().max(1) as f64;
    let shares: Vec<f64> =
        (0..dof).map(|k| samples.clone().filter(|&s| resting[s * dof + k]).count() as f64 / count).collect();
    if shares.iter().all(|s| *s == 0.0) {
        return None;
    }
    Some(Choice::Resting { shares, hold_samples: hold_samples(dt), hold_s: REST_HOLD_S })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A joint that moves, holds for 20 samples, moves, and holds for 3: only the long hold rests;
    /// a second joint that never holds has no rest.
    #[test]
    fn only_holds_of_at_least_the_rest_length_rest() {
        let mut q = Vec::new();
        let mut x = 0.0;
        let mut profile = vec![true; 10];
        profile.extend([false; 20]);
        profile.extend([true; 10]);
        profile.extend([false; 3]);
        profile.extend([true; 10]);
        for (i, moves) in profile.iter().enumerate() {
            if *moves {
                x += 1.0;
            }
            q.extend([x, i as f64]);
        }
        let resting = resting_in_log(&q, 2, 10);
        let first: Vec<bool> = resting.iter().step_by(2).copied().collect();
        // The hold is the 20 samples held plus the one that reached the reading.
        assert_eq!(first.iter().filter(|r| **r).count(), 21);
        assert!(first[9..30].iter().all(|r| *r));
        assert!(!first[30] && !first[40..44].iter().any(|r| *r));
        assert!(!resting.iter().skip(1).step_by(2).any(|r| *r));
    }

    /// Two periods, the joint resting in the second only: the averaged sample rests.
    #[test]
    fn an_averaged_sample_rests_where_any_period_rests() {
        let per = 100;
        let mut q = Vec::new();
        for p in 0..2 {
            for i in 0..per {
                let hold = p == 1 && (40..70).contains(&i);
                q.push(if hold { 40.0 } else { i as f64 });
            }
        }
        let averaging = Some(Averaging { count: 2, samples: per as f64 });
        let resting = resting(&q, 1, averaging, 1e-3, 1);
        assert_eq!(resting.len(), per);
        assert!(resting[40..70].iter().all(|r| *r));
        assert!(!resting[..40].iter().any(|r| *r) && !resting[70..].iter().any(|r| *r));
        let decimated = super::resting(&q, 1, averaging, 1e-3, 10);
        assert_eq!(decimated, (0..10).map(|i| resting[10 * i]).collect::<Vec<_>>());
    }

    /// A joint on an encoder of step 1 moves a step a sample, holds for 5 samples twice (less
    /// than a rest) and moves on. Over the first hold its friction velocity travels 3.2 steps
    /// (half a step entering it at full speed, then 0.6 a sample): a stop, flagged with `widen`
    /// samples either side. Over the second it travels 1.85, as a joint creeping within its step
    /// can: not flagged. A second joint whose positions lie on no
    /// grid (filtered, say) has no stops.
    #[test]
    fn a_hold_over_which_the_friction_velocity_travels_more_than_two_steps_is_a_stop() {
        let dt = 1e-3;
        let (mut q, mut v) = (Vec::new(), Vec::new());
        let mut x = 0.0;
        let mut push = |x: f64, speed: f64, i: usize| {
            q.extend([x, (i as f64 * 0.37).sin() * 0.123]);
            v.extend([speed, 0.0]);
        };
        let mut i = 0;
        for (moves, holds, speed) in [(20, 5, 0.6), (20, 5, 0.3), (20, 0, 1.0)] {
            for _ in 0..moves {
                x += 1.0;
                push(x, 1.0 / dt, i);
                i += 1;
            }
            for _ in 0..holds {
                push(x, speed / dt, i);
                i += 1;
            }
        }
        let widen = 2;
        let stopped = stopped_in_log(&q, &v, 2, dt, widen);
        let first: Vec<usize> = (0..i).filter(|&s| stopped[2 * s]).collect();
        // The run holds the sample that reached the reading and the 5 held: 19..25, widened.
        assert_eq!(first, (19 - widen..25 + widen).collect::<Vec<_>>());
        assert!(!(0..i).any(|s| stopped[2 * s + 1]));
    }
}
