//! The velocity that switches Coulomb friction, and the Coulomb direction columns built from it.
//!
//! Coulomb friction switches with the joint's true velocity. Under closed-loop control a joint
//! dithers around zero speed far faster than the trajectory moves, and its friction switches with
//! that dither; on an open-loop log a faster velocity only lets encoder noise flip the sign. So
//! this velocity has a cut-off of its own, which [`super::cutoff`] chooses by the fit.
//!
//! A period-averaged torque averages the friction of every period: its Coulomb part is the
//! coefficient times the mean over the periods of `law(q̇ₚ)`, each period's own velocity. That is
//! not the law of the mean velocity wherever the periods' velocities straddle zero, as a closed
//! loop's do, so the direction column here is that mean (docs/identification.md gives what it
//! changes).

use crate::model::{CoulombLaws, CoulombShape};
use crate::signal::conditioning::{
    central_difference, every_nth_row, filter_columns, mean_of, whole_periods, Averaging,
};
use crate::signal::filter::{Butterworth, FilterError};

/// The friction velocity of a log: one series per averaged period (a single one for a log that
/// is not periodic), each `samples × dof`, row-major.
#[derive(Clone, Debug)]
pub struct FrictionVelocity {
    /// The cut-off it was filtered at (Hz).
    pub cutoff_hz: f64,
    /// The periods end to end, each `per` values long: kept as filtered, not split into vectors
    /// of their own, since a long log's copy costs as much as its directions.
    values: Vec<f64>,
    per: usize,
}

impl FrictionVelocity {
    /// The velocity averaged over the periods (`samples × dof`): what the averaged positions'
    /// own difference would give, without the friction law.
    pub fn mean(&self) -> Vec<f64> {
        mean_of(&self.periods().collect::<Vec<_>>(), |v| v)
    }

    /// Each period's velocity (`samples × dof`, row-major).
    fn periods(&self) -> std::slice::Chunks<'_, f64> {
        self.values.chunks(self.per.max(1))
    }

    fn period_count(&self) -> usize {
        self.values.len().div_ceil(self.per.max(1)).max(1)
    }

    /// The Coulomb direction of every joint and sample (`samples × dof`), unfiltered: the mean
    /// over the periods of each joint's law of `q̇ₚ`.
    pub fn directions(&self, laws: &CoulombLaws) -> Vec<f64> {
        let dof = laws.shapes().len();
        let mut mean = vec![0.0; self.per];
        let share = 1.0 / self.period_count() as f64;
        // A long log's periods hold 10⁶ samples: runs of rows, which `parallel::map` spreads
        // over the cores. Each sample's mean is summed period by period whatever the runs, so
        // the result does not depend on the cores.
        let run_len = RUN_ROWS * dof.max(1);
        let runs: Vec<(usize, &mut [f64])> =
            mean.chunks_mut(run_len).enumerate().map(|(i, run)| (i * run_len, run)).collect();
        crate::parallel::map(runs, |(start, run)| {
            for period in self.periods() {
                let velocities = period.get(start..).unwrap_or_default();
                // Row by row, each joint's law in turn: a remainder per sample to find the joint
                // cost as much as the laws themselves.
                for (means, row) in run.chunks_mut(dof).zip(velocities.chunks(dof)) {
                    for ((m, v), shape) in means.iter_mut().zip(row).zip(laws.shapes()) {
                        *m += shape.eval(*v) * share;
                    }
                }
            }
        });
        mean
    }

    /// Joint `k`'s Coulomb direction under `shape` at every sample, unfiltered, as
    /// [`Self::directions`] gives it: what one joint's friction-law candidates are built from.
    pub fn joint_directions(&self, k: usize, dof: usize, shape: CoulombShape) -> Vec<f64> {
        let mut mean = vec![0.0; self.per / dof];
        let share = 1.0 / self.period_count() as f64;
        for period in self.periods() {
            for (m, v) in mean.iter_mut().zip(period.iter().skip(k).step_by(dof)) {
                *m += shape.eval(*v) * share;
            }
        }
        mean
    }
}

/// Rows per run of [`FrictionVelocity::directions`].
const RUN_ROWS: usize = 4096;

/// The central difference of a log's positions, before the friction velocity's filter: what
/// every candidate cut-off of that velocity starts from ([`super::cutoff`] tries several).
#[derive(Clone, Debug)]
pub struct RawVelocity {
    dof: usize,
    dt: f64,
    /// The periods placed end to end (or the whole log), `samples × dof`.
    difference: Vec<f64>,
    /// Samples per period, or `None` for a log that is not periodic.
    per: Option<usize>,
}

impl RawVelocity {
    /// The velocity of the raw positions `q` (`N × dof`) by central differences, to be filtered
    /// ([`Self::filtered`]). With `averaging`, the log's whole periods, resampled as the positions
    /// are, are placed end to end, which is itself a periodic signal, and differenced (and later
    /// filtered) circularly; `dt` is then the resampled step.
    pub fn of_log(q: &[f64], dof: usize, averaging: Option<Averaging>, dt: f64) -> Self {
        let (difference, per) = match averaging {
            None => (central_difference(q, dof, dt, false), None),
            Some(a) => (central_difference(&whole_periods(q, dof, a), dof, dt, true), Some(a.per())),
        };
        Self { dof, dt, difference, per }
    }

    /// The velocity filtered at `cutoff_hz` (Butterworth of `order`, forward and backward), split
    /// into its periods, each thinned to every `decimate`-th sample.
    pub fn filtered(&self, order: usize, cutoff_hz: f64, decimate: usize) -> Result<FrictionVelocity, FilterError> {
        let filter = Butterworth::lowpass(order, cutoff_hz, 1.0 / self.dt)?;
        let dof = self.dof;
        let v = filter_columns(&filter, &self.difference, dof, self.per.is_some())?;
        let per = self.per.map_or(v.len(), |per| per * dof);
        let values = match decimate {
            1 => v,
            _ => v.chunks(per).flat_map(|p| every_nth_row(p, dof, decimate)).collect(),
        };
        let per = per.div_ceil(dof * decimate) * dof;
        Ok(FrictionVelocity { cutoff_hz, values, per })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Thinning keeps every `decimate`-th sample of each period, from its first, whatever the
    /// period's length: three periods of 101 samples of two joints thinned by 2 are the full
    /// velocity's samples 0, 2, …, 100 of each.
    #[test]
    fn a_thinned_friction_velocity_is_every_nth_sample_of_each_period() {
        let (dt, per, dof) = (1e-3, 101, 2);
        let q: Vec<f64> = (0..3 * per * dof)
            .map(|i| ((i / dof) as f64 * dt * std::f64::consts::TAU * 20.0 / per as f64 * (1 + i % dof) as f64).sin())
            .collect();
        let raw = RawVelocity::of_log(&q, dof, Some(Averaging { count: 3, samples: per as f64 }), dt);
        let (full, thinned) = (raw.filtered(5, 50.0, 1).unwrap(), raw.filtered(5, 50.0, 2).unwrap());
        assert_eq!(thinned.mean().len(), 51 * dof);
        assert_eq!(thinned.mean(), every_nth_row(&full.mean(), dof, 2));
        let laws = CoulombLaws::undeclared(dof);
        assert_eq!(thinned.directions(&laws), every_nth_row(&full.directions(&laws), dof, 2));
        let shape = CoulombShape::Sign;
        assert_eq!(thinned.joint_directions(1, dof, shape), every_nth_row(&full.joint_directions(1, dof, shape), 1, 2));
    }

    /// Two periods of a sine velocity, one with a dither around its zero crossings: the mean of
    /// the signs differs from the sign of the mean where the periods disagree.
    #[test]
    fn the_direction_of_an_average_is_the_average_of_the_directions() {
        let (dt, per) = (1e-3, 2000);
        let mut q = Vec::new();
        for p in 0..2 {
            for i in 0..per {
                let t = i as f64 * dt;
                let dither = if p == 1 { 5e-4 * (2.0 * std::f64::consts::PI * 40.0 * t).sin() } else { 0.0 };
                q.push((2.0 * std::f64::consts::PI * t / 2.0).sin() + dither);
            }
        }
        let averaging = Some(Averaging { count: 2, samples: per as f64 });
        let v = RawVelocity::of_log(&q, 1, averaging, dt).filtered(5, 100.0, 1).unwrap();
        let directions = v.directions(&CoulombLaws::undeclared(1));
        let of_mean: Vec<f64> = v.mean().iter().map(|x| CoulombShape::Sign.eval(*x)).collect();
        // Every direction is a mean of two signs; somewhere near the zero crossings (t = 0.5 s,
        // 1.5 s) the dithered period's sign flips against the clean one's.
        assert!(directions.iter().all(|d| [-1.0, 0.0, 1.0].contains(d)));
        assert!(directions.contains(&0.0), "the periods never disagree");
        let disagree = directions.iter().zip(&of_mean).filter(|(a, b)| a != b).count();
        assert!(disagree > 0 && disagree < per / 10, "{disagree} samples differ");
        // Away from the crossings every period agrees.
        assert_eq!(directions[per / 8], 1.0);
        assert_eq!(directions[per / 2], -1.0);
    }
}
