//! The cut-offs identification uses when the user sets none: the low-pass cut-off of every signal,
//! and that of the velocity the Coulomb columns switch with.
//!
//! Each is chosen by what the model fitted with it explains, judged where the choice cannot
//! flatter itself (docs/identification.md, "Preprocessing", gives the measurements):
//!
//! - **The friction velocity**, at a given cut-off, by the training fit. Every candidate is
//!   judged against the same filtered torque with the same parameters, so the best fit is the
//!   velocity whose switching explains the torque best: a fast one where a controlled joint
//!   dithers around zero speed, the main cut-off where a faster one only lets encoder noise flip
//!   the sign.
//! - **The cut-off** by the fitted model's prediction of the torque *before* filtering. Judged
//!   against its own filtered torque every cut-off would look better the lower it is, because
//!   filtering takes the noise out of the target along with the motion. The unfiltered torque is
//!   one target for all: a cut-off too low loses motion the model needs, one too high lets the
//!   encoders' noise into q̈, and both show as a larger error. A periodic log's halves predict
//!   each other's torque (`Folds`), so that a closed loop's noise cannot flatter the score.
//!
//! The candidates run from the lowest cut-off the log allows to [`SEARCH_ABOVE_SPECTRAL`] times
//! the one the motion's spectrum suggests ([`super::data_choices`]), within a quarter of the sample rate.

use super::data_choices::{
    best_predicting, geometric_grid, most_accurate_prediction, Equal, Prediction, Prefer, EQUAL_PREDICTION_POINTS,
    EQUAL_PREDICTION_SIGMAS,
};
use super::estimate::{
    apply, coulomb_positions, filter_each_column, joint_metrics, leave_out_rests, ols_beta_and_metrics, put_coulomb,
    regressor_rows,
};
use super::log::{Declared, Log};
use super::options::PreprocessOptions;
use super::preprocess::{
    edge_limited_cutoff_hz, filtered_motion, preprocess, Choices, Conditioned, PreprocessError, Preprocessed,
    MIN_CUTOFF_HZ,
};
use crate::choices::{Choice, Concern};
use crate::signal::conditioning::{filter_columns, mean_of, periods_of};
use crate::signal::filter::Butterworth;
use std::borrow::Cow;

/// The search goes this far above the cut-off the motion's spectrum suggests: the torque holds
/// products and harmonics of the motion (Coriolis terms, gravity's sine of the angle) above the
/// motion's own bandwidth, and a closed loop's fast response shows in it.
pub const SEARCH_ABOVE_SPECTRAL: f64 = 4.0;

/// A candidate is fitted on the log thinned to this many samples per period of its cut-off,
/// after filtering: the fit's figures do not change, and the search is several times faster on
/// long logs.
const SAMPLES_PER_CUTOFF: f64 = 20.0;

/// At most this many samples are fitted per candidate velocity, and this many scored per
/// cut-off: evenly spread, they give the fits' figures as all of a long log's would (to a few
/// hundredths of a point), at a bounded cost.
const MOST_FITTED: usize = 4_000;
const MOST_SCORED: usize = 10_000;

/// Every `step`-th of `range`, with `step` at least `least` and large enough to keep at most
/// `most`.
fn spread(range: std::ops::Range<usize>, least: usize, most: usize) -> Vec<usize> {
    let step = least.max(range.len().div_ceil(most)).max(1);
    range.step_by(step).collect()
}

/// Blocks of the paired comparison span this many periods of the lowest cut-off: the
/// difference between two filtered models' errors is correlated over the filters' memory...
const COMPARISON_BLOCK_PERIODS: f64 = 2.0;

/// ... but are never fewer than this: a standard error from fewer blocks is itself too uncertain
/// to tell anything apart (a log a few periods of its lowest cut-off long).
const COMPARISON_BLOCKS: usize = 10;

/// The search starts at this many times the motion's bandwidth, below which the forward–backward
/// Butterworth bends the motion's highest harmonic by more than 0.1 % (order 5: |H|² = 1/(1 +
/// 0.5¹⁰)): for a periodic log, whose bandwidth is the highest harmonic that repeats, always;
/// otherwise where that is below [`MIN_CUTOFF_HZ`] (a slow motion), the spectrum's bandwidth of
/// a log that does not repeat being an estimate. A cut-off that bends what the torque depends on
/// predicts the unfiltered torque worse, but where a closed loop's response to encoder noise
/// dominates the torque that does not show: a periodic log at 9 Hz was fitted at 11 Hz, and
/// its yaw predicted 9 % off (1.5 % at 13 Hz).
pub const SEARCH_FROM_BANDWIDTH: f64 = 2.0;

/// Where a cut-off search starts for a motion of `bandwidth_hz` ([`SEARCH_FROM_BANDWIDTH`]):
/// `repeats` when that bandwidth is the highest harmonic that repeats from period to period,
/// which is motion however small, so that a cut-off bending it distorts what the torque depends
/// on (which a noise-dominated torque cannot show); otherwise no higher than [`MIN_CUTOFF_HZ`].
pub fn motion_floor_hz(bandwidth_hz: Option<f64>, repeats: bool) -> f64 {
    match (bandwidth_hz, repeats) {
        (Some(b), true) => SEARCH_FROM_BANDWIDTH * b,
        (Some(b), false) => (SEARCH_FROM_BANDWIDTH * b).min(MIN_CUTOFF_HZ),
        (None, _) => MIN_CUTOFF_HZ,
    }
}

/// The friction velocity's candidates are one octave apart: the fit changes little within one.
const FRICTION_STEP: usize = super::data_choices::CUTOFFS_PER_OCTAVE;

/// One candidate cut-off, with the friction velocity that fitted best at it.
#[derive(Clone, Debug)]
struct Trial {
    cutoff_hz: f64,
    friction_hz: f64,
    /// Mean over the joints of FP% on the unfiltered torque.
    predicted_fp: f64,
    /// Squared error of that prediction at each scored sample, each joint's over its torque's
    /// variance, summed over the joints: what the cut-offs are compared by.
    errors: Vec<f64>,
    /// Mean training FP% of each friction velocity tried: what chose it.
    frictions: Vec<(f64, f64)>,
    /// Mean training FP% with the chosen one: what breaks ties between cut-offs.
    training_fp: f64,
}

/// What the filtered torque is fitted against, which decides how low a periodic log's cut-off
/// may go ([`SEARCH_FROM_BANDWIDTH`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Against {
    /// The regressor of the filtered motion alone (least squares): the filter must not bend the
    /// motion, since filtering the torque and filtering the motion the torque is computed from
    /// differ where it does.
    Regressor,
    /// The loop simulated with the estimate, through the same filter (IDIM-IV's instruments,
    /// DIDIM's torque): a filter that bends the motion bends the simulated loop alike, and a
    /// lower cut-off lets less of the loop's noise through. On an independent closed loop with a
    /// 2 Hz drive disturbance IDIM-IV's 3σ covered 100, 91 and 73 % of the base parameters at 1,
    /// 4 and 11 Hz; with the floor raised to twice the motion's bandwidth it covered 89 %
    /// over three seeds, and DIDIM cycled on one of four (docs/identification.md).
    SimulatedLoop,
}

/// The log preprocessed at the cut-offs that explain it best, its choices saying why. What the
/// user set is kept.
pub fn preprocess_for_fit(
    declared: Declared,
    log: Log,
    options: &PreprocessOptions,
    against: Against,
) -> Result<Preprocessed, PreprocessError> {
    Reading::of(declared, log, options)?.preprocess_for_fit(declared, against)
}

/// A log read once for every search of its cut-offs (identification searches again with each
/// round of Coulomb laws). None of it depends on the laws.
pub struct Reading<'a> {
    log: Log<'a>,
    options: PreprocessOptions,
    /// What the searches share; `None` where the options leave nothing to search.
    searched: Option<Searched<'a>>,
}

/// What every search of one log shares: the reference preprocessing, which finds the period,
/// the rate and the spectral rule, and the log conditioned for the trials.
struct Searched<'a> {
    reference: Preprocessed,
    /// The options every trial shares: the reference's period, no decimation.
    fixed: PreprocessOptions,
    conditioned: Conditioned<'a>,
}

impl<'a> Reading<'a> {
    /// Read `log` for the searches `options` ask for: none where the cut-off is given, and the
    /// friction velocity's too or `declared`'s base parameters have no Coulomb column.
    pub fn of(declared: Declared, log: Log<'a>, options: &PreprocessOptions) -> Result<Self, PreprocessError> {
        let dof = declared.model.dof();
        let coulomb = !coulomb_positions(declared.model, &declared.base.independent).is_empty();
        let searched = match options.cutoff_hz.is_some() && (options.friction_cutoff_hz.is_some() || !coulomb) {
            true => None,
            false => {
                // The period, the rate and the spectral rule, found once; every candidate keeps the period.
                let reference =
                    preprocess(log.t, log.q, log.tau, dof, &PreprocessOptions { decimate: 1, ..options.clone() })?;
                let fixed = PreprocessOptions {
                    period_s: reference.period_s,
                    periods: Some(1),
                    decimate: 1,
                    ..options.clone()
                };
                let conditioned = Conditioned::of(log.t, log.q, log.tau, dof, &fixed)?;
                Some(Searched { reference, fixed, conditioned })
            }
        };
        Ok(Self { log, options: options.clone(), searched })
    }

    /// The log preprocessed at the cut-offs that explain it best with `declared`'s Coulomb laws
    /// (whose base parameters must be those it was read with), or as the options ask where they
    /// leave nothing to search.
    pub fn preprocess_for_fit(&self, declared: Declared, against: Against) -> Result<Preprocessed, PreprocessError> {
        let Self { log, options, searched } = self;
        let dof = declared.model.dof();
        let Some(Searched { reference, fixed, conditioned }) = searched else {
            return preprocess(log.t, log.q, log.tau, dof, options);
        };
        let mut search = Search::new(declared, *log, reference, fixed, against, conditioned);
        let cutoffs = match options.cutoff_hz {
            Some(cutoff) => vec![cutoff],
            None => search.grid.iter().copied().take_while(|c| *c <= search.top * (1.0 + 1e-9)).collect(),
        };
        search.filter_velocities(&cutoffs, options.friction_cutoff_hz)?;
        // The trials are independent; in order, so that ties are broken as before.
        let tried = crate::parallel::map(cutoffs, |cutoff| search.trial(cutoff, options.friction_cutoff_hz));
        let trials: Vec<Trial> = tried.into_iter().collect::<Result<Vec<_>, _>>()?.into_iter().flatten().collect();
        let Some(best) = chosen(&trials, search.block_rows()).cloned() else {
            // No candidate could be fitted: preprocess as asked, and let the fit say why.
            return preprocess(log.t, log.q, log.tau, dof, options);
        };
        let chosen = PreprocessOptions {
            cutoff_hz: Some(best.cutoff_hz),
            friction_cutoff_hz: Some(best.friction_hz),
            decimate: options.decimate,
            ..fixed.clone()
        };
        let mut pre = match options.decimate {
            1 => conditioned.at_cutoff(&chosen)?,
            _ => preprocess(log.t, log.q, log.tau, dof, &chosen)?,
        };
        pre.choices = explain(reference, &pre.choices, options, &trials, &best, search.length_limited);
        Ok(pre)
    }
}

/// What every trial shares: the model, the log, the grid of cut-offs, and the friction
/// velocities' Coulomb directions, computed once per cut-off of the grid that a trial tries.
struct Search<'a> {
    declared: Declared<'a>,
    fixed: &'a PreprocessOptions,
    reference: &'a Preprocessed,
    /// Cut-offs [`CUTOFFS_PER_OCTAVE`] per octave from the lowest worth trying to a quarter of
    /// the sample rate; the main cut-off's candidates stop at `top`.
    grid: Vec<f64>,
    top: f64,
    /// Whether the lowest was set by the log's length (the filter's start-up at its ends).
    length_limited: bool,
    /// The samples every candidate is scored on: clear of the filter's start-up at the lowest
    /// cut-off, so that all are scored alike.
    scored: Vec<usize>,
    /// The unfiltered Coulomb directions of the friction velocity at each cut-off of the grid
    /// that some trial tries ([`Self::filter_velocities`]).
    directions: Vec<Option<Vec<f64>>>,
    /// A periodic log's periods in two halves (an averaged log holds at least two periods).
    folds: Option<Folds>,
    /// The log read with `fixed`, which each trial filters at its cut-off.
    conditioned: &'a Conditioned<'a>,
}

/// A periodic log's even and odd periods, each half averaged: the positions of one half predict
/// the torque of the other. In a closed loop the controller turns the encoders' noise into
/// torque, so a model scored on the torque of the positions it is built from is rewarded for a
/// cut-off that lets that noise in (it learns the controller's damping as friction); the other
/// half's torque holds the same motion but noise of its own.
struct Folds {
    /// Mean positions and mean unfiltered torque of each half, one period of `per()` samples.
    positions: [Vec<f64>; 2],
    torques: [Vec<f64>; 2],
}

impl Folds {
    fn of(log: &Log, reference: &Preprocessed, dof: usize) -> Option<Self> {
        let averaging = reference.averaging()?;
        let halves = |x: &[f64]| -> [Vec<f64>; 2] {
            let periods = periods_of(x, dof, averaging);
            let half = |parity: usize| -> Vec<&Vec<f64>> { periods.iter().skip(parity).step_by(2).collect() };
            [mean_of(&half(0), |v| v), mean_of(&half(1), |v| v)]
        };
        Some(Self { positions: halves(log.q), torques: halves(log.tau) })
    }
}

impl<'a> Search<'a> {
    fn new(
        declared: Declared<'a>,
        log: Log<'a>,
        reference: &'a Preprocessed,
        fixed: &'a PreprocessOptions,
        against: Against,
        conditioned: &'a Conditioned<'a>,
    ) -> Self {
        let fs = reference.sample_rate_hz;
        let n = reference.samples();
        let shortest = edge_limited_cutoff_hz(log.t.len(), fs, reference.periodic);
        let floor =
            motion_floor_hz(reference.bandwidth_hz, reference.periodic && against == Against::Regressor).max(shortest);
        let length_limited = floor == shortest;
        let grid = geometric_grid(floor, 0.25 * fs);
        let top = (SEARCH_ABOVE_SPECTRAL * reference.cutoff_hz).clamp(floor, 0.25 * fs);
        let edge = match reference.periodic {
            true => 0,
            false => (super::preprocess::EDGE_CUTOFF_PERIODS * fs / floor).ceil() as usize,
        };
        let scored = spread(edge.min(n / 2)..n.saturating_sub(edge).max(n / 2), 1, MOST_SCORED);
        let directions = vec![None; grid.len()];
        let folds = Folds::of(&log, reference, declared.model.dof());
        Self { declared, fixed, reference, grid, top, length_limited, scored, directions, folds, conditioned }
    }

    /// Filter the friction velocity at every grid point the trials at `cutoffs` try, on every
    /// core: on a long log this filtering is most of the search (each grid point's velocity is
    /// the whole log, filtered), and each is needed by the trials a quarter of the grid apart.
    fn filter_velocities(&mut self, cutoffs: &[f64], user: Option<f64>) -> Result<(), PreprocessError> {
        let mut needed: Vec<usize> =
            cutoffs.iter().flat_map(|&c| self.frictions(c, user)).filter_map(|(_, at)| at).collect();
        needed.sort_unstable();
        needed.dedup();
        let (raw, order, laws) =
            (self.conditioned.raw_velocity(), self.reference.order, &self.declared.model.coulomb_laws);
        let grid = &self.grid;
        let filtered = crate::parallel::map(needed.clone(), |i| {
            raw.filtered(order, grid[i], 1).map(|velocity| velocity.directions(laws))
        });
        for (i, directions) in needed.into_iter().zip(filtered) {
            self.directions[i] = Some(directions?);
        }
        Ok(())
    }

    /// The unfiltered Coulomb directions of the friction velocity at grid point `i` (full rate).
    fn directions(&self, i: usize) -> &[f64] {
        self.directions[i].as_deref().expect("the trials' friction velocities are filtered before they run")
    }

    /// The friction velocities tried at `cutoff`: the user's, or grid points an octave apart
    /// through `cutoff` (through the grid's lowest when `cutoff` is off the grid, and `cutoff`
    /// itself), from the lowest to a quarter of the sample rate. A velocity slower than the
    /// cut-off can switch friction best: it crosses zero where a smooth motion does, without the
    /// encoder's noise.
    fn frictions(&self, cutoff: f64, user: Option<f64>) -> Vec<(f64, Option<usize>)> {
        if let Some(f) = user {
            return vec![(f.min(0.25 * self.reference.sample_rate_hz), None)];
        }
        let at = self.grid.iter().position(|g| (g / cutoff - 1.0).abs() < 1e-9);
        let first = at.map_or(0, |i| i % FRICTION_STEP);
        let mut candidates: Vec<(f64, Option<usize>)> =
            (first..self.grid.len()).step_by(FRICTION_STEP).map(|i| (self.grid[i], Some(i))).collect();
        if at.is_none() {
            candidates.push((cutoff, None));
        }
        candidates
    }

    /// Fit at `cutoff` with each friction velocity, keep the best-fitting one, and score the
    /// model on the unfiltered torque. `None` when the log cannot be filtered or fitted there.
    fn trial(&self, cutoff: f64, user_friction: Option<f64>) -> Result<Option<Trial>, PreprocessError> {
        let Declared { model, base, .. } = self.declared;
        let (dof, fs) = (model.dof(), self.reference.sample_rate_hz);
        let options = PreprocessOptions { cutoff_hz: Some(cutoff), ..self.fixed.clone() };
        let pre = match self.conditioned.at_cutoff(&options) {
            Ok(pre) => pre,
            Err(PreprocessError::TooShortForCutoff { .. }) => return Ok(None),
            Err(e) => return Err(e),
        };
        let columns = &base.independent;
        // The Coulomb columns of `w` are replaced by each candidate's in turn.
        let (mut w, rows) = self.filtered_columns(&pre, cutoff)?;
        let mut tau = rows_of(&pre.tau, dof, &rows);
        let positions = coulomb_positions(model, columns);
        let filter = Butterworth::lowpass(pre.order, cutoff, fs)?;
        let mut frictions = Vec::new();
        // The best so far: its velocity's cut-off, training FP%, β and Coulomb directions.
        type Best<'d> = (f64, f64, Vec<f64>, Cow<'d, [f64]>);
        let mut best: Option<Best> = None;
        for (friction_hz, at) in self.frictions(cutoff, user_friction) {
            let directions: Cow<[f64]> = match at {
                Some(i) => self.directions(i).into(),
                None => self
                    .conditioned
                    .raw_velocity()
                    .filtered(pre.order, friction_hz, 1)?
                    .directions(&model.coulomb_laws)
                    .into(),
            };
            let filtered = filter_columns(&filter, &directions, dof, pre.periodic)?;
            put_coulomb(&mut w, dof, &positions, &filtered, &rows);
            leave_out_rests(&pre, &mut w, &mut tau, rows.iter().copied());
            // A velocity with which the parameters cannot be fitted is simply not a candidate.
            let Ok((beta, metrics)) = ols_beta_and_metrics(&w, &tau, dof, base) else { continue };
            let training = metrics.fp_percent.iter().sum::<f64>() / dof as f64;
            frictions.push((friction_hz, training));
            if best.as_ref().is_none_or(|b| training > b.1) {
                best = Some((friction_hz, training, beta, directions));
            }
        }
        let Some((friction_hz, training_fp, beta, directions)) = best else { return Ok(None) };
        let scored_columns = |motion: &Preprocessed| {
            let mut v = regressor_rows(model, motion, columns, &self.scored);
            put_coulomb(&mut v, dof, &positions, &directions, &self.scored);
            v
        };
        let (predicted_fp, errors) = match &self.folds {
            None => self.unfiltered_fit(&pre.tau_unfiltered, &scored_columns(&pre), &beta, &pre.resting),
            Some(folds) => {
                // The fit is done with `pre`'s own motion: each half's takes its place in turn.
                let mut moved = pre;
                let mut scores = Vec::with_capacity(2);
                for (half, other) in [(0, 1), (1, 0)] {
                    let half_q = &folds.positions[half];
                    (moved.q, moved.qd, moved.qdd) =
                        filtered_motion(&filter, half_q, dof, 1.0 / fs, true, self.fixed.filter_derivatives)?;
                    scores.push(self.unfiltered_fit(
                        &folds.torques[other],
                        &scored_columns(&moved),
                        &beta,
                        &moved.resting,
                    ));
                }
                let fp = scores.iter().map(|s| s.0).sum::<f64>() / 2.0;
                (fp, scores.into_iter().flat_map(|s| s.1).collect())
            }
        };
        Ok(Some(Trial { cutoff_hz: cutoff, friction_hz, predicted_fp, errors, frictions, training_fp }))
    }

    /// The regressor's base columns filtered like the torque ([`filter_each_column`]) at the
    /// rows a candidate is fitted on, and those rows (at most [`MOST_FITTED`], at least
    /// [`SAMPLES_PER_CUTOFF`] per period of the cut-off). The columns are computed and filtered
    /// on the log thinned to that many samples per period, which keeps their content (products of
    /// a motion filtered at the cut-off) far below the thinned rate's Nyquist frequency. The
    /// Coulomb columns are left for the caller: they step, and are filtered at the full rate.
    fn filtered_columns(
        &self,
        pre: &Preprocessed,
        cutoff: f64,
    ) -> Result<(faer::Mat<f64>, Vec<usize>), PreprocessError> {
        let Declared { model, base, .. } = self.declared;
        let (n, dof, fs) = (pre.samples(), model.dof(), pre.sample_rate_hz);
        let most = ((fs / (SAMPLES_PER_CUTOFF * cutoff)).floor() as usize).max(1);
        // A periodic log is filtered circularly: its thinned samples must still be whole periods.
        let thin = match pre.periodic {
            true => (1..=most).rev().find(|d| n % d == 0).unwrap_or(1),
            false => most,
        };
        let thinned: Vec<usize> = (0..n).step_by(thin).collect();
        let mut w = regressor_rows(model, pre, &base.independent, &thinned);
        let filter = Butterworth::lowpass(pre.order, cutoff, fs / thin as f64)?;
        filter_each_column(&mut w, dof, &filter, pre.periodic);
        let settled: Vec<usize> = (0..thinned.len()).filter(|&i| pre.settled.contains(&thinned[i])).collect();
        let kept = spread(0..settled.len(), 1, MOST_FITTED);
        let picked =
            faer::Mat::from_fn(kept.len() * dof, w.ncols(), |r, c| w[(settled[kept[r / dof]] * dof + r % dof, c)]);
        Ok((picked, kept.iter().map(|&i| thinned[settled[i]]).collect()))
    }

    /// The model `beta` (its columns at the scored samples, `v`, the Coulomb ones unfiltered)
    /// against the unfiltered torque `tau` (one period, or the whole log) there: mean FP% over the
    /// joints, and each sample's squared error summed over the joints, each joint's divided by its
    /// torque's variance.
    /// Resting joints' samples (`resting`, [`Preprocessed::resting`]) are not scored.
    fn unfiltered_fit(&self, tau: &[f64], v: &faer::Mat<f64>, beta: &[f64], resting: &[bool]) -> (f64, Vec<f64>) {
        let dof = self.declared.model.dof();
        let mut measured = rows_of(tau, dof, &self.scored);
        let mut predicted = apply(v, beta);
        for (r, k) in (0..measured.len()).map(|r| (r, r % dof)) {
            if resting[self.scored[r / dof] * dof + k] {
                (measured[r], predicted[r]) = (0.0, 0.0);
            }
        }
        let fp = joint_metrics(&measured, &predicted, dof).fp_percent.iter().sum::<f64>() / dof as f64;
        let samples = self.scored.len() as f64;
        let variances: Vec<f64> = (0..dof)
            .map(|k| {
                let column = || measured.iter().skip(k).step_by(dof);
                let mean = column().sum::<f64>() / samples;
                (column().map(|x| (x - mean).powi(2)).sum::<f64>() / samples).max(f64::MIN_POSITIVE)
            })
            .collect();
        let errors = measured
            .chunks(dof)
            .zip(predicted.chunks(dof))
            .map(|(t, p)| (0..dof).map(|k| (t[k] - p[k]).powi(2) / variances[k]).sum())
            .collect();
        (fp, errors)
    }

    /// Scored samples per comparison block: [`COMPARISON_BLOCK_PERIODS`] periods of the lowest
    /// cut-off, or a [`COMPARISON_BLOCKS`]th of them when that is shorter.
    fn block_rows(&self) -> usize {
        let span = self.scored.last().zip(self.scored.first()).map_or(1, |(l, f)| l - f + 1);
        let per_row = span as f64 / self.scored.len().max(1) as f64;
        let by_memory =
            (COMPARISON_BLOCK_PERIODS * self.reference.sample_rate_hz / self.grid[0] / per_row).ceil() as usize;
        by_memory.min(self.scored.len() / COMPARISON_BLOCKS).max(1)
    }
}

/// The rows `rows` of a row-major signal of `dof` columns, stacked.
fn rows_of(x: &[f64], dof: usize, rows: &[usize]) -> Vec<f64> {
    rows.iter().flat_map(|&s| x[s * dof..(s + 1) * dof].iter().copied()).collect()
}

/// The trials as the decision rule reads them.
fn predictions(trials: &[Trial]) -> Vec<Prediction<'_>> {
    trials
        .iter()
        .map(|t| Prediction {
            cutoff_hz: t.cutoff_hz,
            errors: &t.errors,
            fp: t.predicted_fp,
            training_fp: t.training_fp,
        })
        .collect()
}

/// The trial [`best_predicting`] chooses.
fn chosen(trials: &[Trial], block_rows: usize) -> Option<&Trial> {
    best_predicting(&predictions(trials), Equal::Paired { block_rows }, Prefer::BestInBandFit).map(|i| &trials[i])
}

/// The trial whose prediction of the unfiltered torque has the highest mean FP%.
fn most_accurate(trials: &[Trial]) -> Option<&Trial> {
    most_accurate_prediction(&predictions(trials)).map(|i| &trials[i])
}

/// The reference's choices (period, spectral rule) with the cut-off line replaced by the search's,
/// the lines that depend on the cut-off from the final preprocessing, the friction line replaced
/// by its search's, and a warning when a choice sits at the edge of what was tried.
fn explain(
    reference: &Preprocessed,
    last: &Choices,
    options: &PreprocessOptions,
    trials: &[Trial],
    best: &Trial,
    length_limited: bool,
) -> Choices {
    let mut reasons: Vec<Choice> = reference.choices.reasons.iter().filter(|r| !r.follows_cutoff()).cloned().collect();
    let mut warnings = reference.choices.warnings.clone();
    let at = reasons.iter().position(Choice::is_cutoff).unwrap_or(reasons.len());
    if options.cutoff_hz.is_none() {
        let (lo, hi) = (trials[0].cutoff_hz, trials[trials.len() - 1].cutoff_hz);
        let most = most_accurate(trials).unwrap_or(best);
        let searched = Choice::CutoffSearched {
            cutoff_hz: best.cutoff_hz,
            trials: trials.iter().map(|t| [t.cutoff_hz, t.predicted_fp]).collect(),
            periodic: reference.periodic,
            most_accurate_hz: most.cutoff_hz,
            training_fp: best.training_fp,
            predicted_fp: best.predicted_fp,
            most_accurate_fp: most.predicted_fp,
            sigmas: EQUAL_PREDICTION_SIGMAS,
            points: EQUAL_PREDICTION_POINTS,
            spectral: reasons.get(at).cloned().map(Box::new),
        };
        match at < reasons.len() {
            true => reasons[at] = searched,
            false => reasons.push(searched),
        }
        if trials.len() > 1 && most.cutoff_hz == lo && length_limited {
            warnings.push(Concern::BestAtLowestCutoff { cutoff_hz: lo });
        }
        if trials.len() > 1 && best.cutoff_hz == hi && hi >= 0.25 * reference.sample_rate_hz * (1.0 - 1e-9) {
            warnings.push(Concern::BestAtHighestCutoff { cutoff_hz: hi });
        }
    }
    reasons.extend(last.reasons.iter().filter(|r| r.follows_cutoff() && !r.is_friction()).cloned());
    reasons.push(match options.friction_cutoff_hz {
        Some(_) => Choice::FrictionCutoff { cutoff_hz: best.friction_hz, given: true, at_most_quarter: true },
        None => Choice::FrictionCutoffSearched {
            cutoff_hz: best.friction_hz,
            band_hz: best.cutoff_hz,
            trials: best.frictions.iter().map(|&(f, fp)| [f, fp]).collect(),
        },
    });
    Choices { reasons, warnings }
}
