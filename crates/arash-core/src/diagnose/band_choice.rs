//! The diagnosis's band chosen from the data: the cut-off in which the declared model predicts
//! held-out torque as well as it can, by the rule identification's cut-off uses
//! ([`best_predicting`]).
//!
//! The diagnosis compares models in its band, so the band decides what it can see. Too wide, and
//! q̈ differenced from coarse or slow encoders is mostly noise: the declared model predicts worse,
//! every column correlated with the inertial torque takes up the errors-in-variables bias, and
//! real effects drown in what no model explains (issue 44: a 200 Hz surgical arm's held-out error
//! was 0.34 of its torque at 20 Hz and 0.065 at 4 Hz). Too narrow, and the motion the model
//! explains is cut away. Each candidate cut-off is judged by how well the declared model fitted in
//! it predicts the *unfiltered* torque of data it was not fitted on (the validation runs, or the
//! odd blocks of the training log): one target for every candidate, which a band cannot flatter
//! by filtering its own noise away. Of the candidates that predict as well as the best (within
//! the paired test's standard errors), the widest is kept: equal predictions hold the same
//! predictable content, and the widest holds it in the most independent samples, which gives the
//! Wald test its batches and tells effects apart that differ in their faster content. What it
//! holds above the narrowest of them, the declared model does not predict; the held-out gains
//! are judged above it (`noise.rs`).
//!
//! A band the user sets is used as set; the report says when it predicts held-out data worse than
//! the data's choice.

use std::borrow::Cow;

use super::band::{velocity_resolved_cutoff, Band, Positions};
use super::options::{DiagnoseError, DiagnoseOptions, DIAGNOSIS_CUTOFF_HZ, DIAGNOSIS_CUTOFF_SHARE};
use super::prepare::{declared_columns, filtered, kept_samples, lowest_kept_cutoff_hz, stride};
use super::regression::{gram, rhs, solve_scaled, Column, Rows};
use super::weighted_fit::{heldout_split, Split, BLOCK_MEMORIES, MIN_HELDOUT_BLOCKS};
use super::Runs;
use crate::base_parameters::BaseParameters;
use crate::choices::{Choice, Concern};
use crate::effects::EffectKind;
use crate::model::Model;
use crate::signal::cutoff::{motion_floor_hz, SEARCH_ABOVE_SPECTRAL};
use crate::signal::data_choices::{
    as_good_as_best, best_predicting, geometric_grid, Equal, Prediction, Prefer, EQUAL_PREDICTION_SIGMAS,
};
use crate::signal::estimate::joint_metrics;
use crate::signal::filter::Butterworth;
use crate::signal::friction_law::{laws_for_fit, ChosenLaws, RawPositions};
use crate::signal::log::Log;
use crate::signal::preprocess::{
    edge_limited_cutoff_hz, validate_log, PreprocessError, Preprocessed, CUTOFF_PER_BANDWIDTH,
};

/// Fitted and scored samples per candidate cut-off: evenly spread, they rank the candidates as
/// all of a long log's would, at a bounded cost.
const MOST_FITTED: usize = 4_000;
const MOST_SCORED: usize = 6_000;

/// The band is chosen on at most this many samples of each log, its first: the band is a matter
/// of the sensors and the motion, which a minute at 1 kHz shows as well as five, and every
/// candidate filters all of what it is given.
const MOST_SEARCHED: usize = 60_000;

/// The band a diagnosis filters in, why, and the Coulomb laws chosen with it.
pub(super) struct BandChoice {
    pub(super) band: Band,
    /// The lines that replace the preprocessing's own for the cut-off and the friction velocity,
    /// and the friction laws' when they were chosen.
    pub(super) reasons: Vec<Choice>,
    pub(super) warnings: Vec<Concern>,
    /// The narrowest band that predicts as well: what the chosen one holds above it, the declared
    /// model does not predict (`noise.rs`, [`super::noise::NoiseFloor::above`]).
    pub(super) narrowest: Band,
    /// Each joint's Coulomb law chosen from the data (when the robot declares none and the
    /// declared model is refitted).
    pub(super) laws: Option<ChosenLaws>,
}

/// Choose the diagnosis's band for `train` (and `validation`, held out), and with it, when
/// `choose_laws`, each joint's Coulomb law.
pub(super) fn choose_band(
    model: &Model,
    base: &BaseParameters,
    train: Log,
    validation: Option<&Runs>,
    options: &DiagnoseOptions,
    choose_laws: bool,
) -> Result<BandChoice, DiagnoseError> {
    let dof = model.dof();
    let fs = 1.0 / validate_log(train.t, train.q, train.tau, dof).map_err(DiagnoseError::Training)?;
    if let Some(c) = options.preprocess.cutoff_hz.filter(|c| !crate::signal::filter::below_nyquist(*c, fs)) {
        return Err(DiagnoseError::BandAboveNyquist { cutoff_hz: c, nyquist_hz: 0.5 * fs });
    }
    let positions = Positions::of(train.q, dof, fs);
    let order = options.preprocess.order;
    let search = Search::new(model, base, train, validation, options, &positions)?;
    // The laws are chosen at the widest band first, so that the candidates are judged with them,
    // and again at the band chosen.
    let mut model = Cow::Borrowed(model);
    let mut laws = None;
    if choose_laws {
        laws = search.laws(&model, search.top)?;
        if let Some(chosen) = &laws {
            model.to_mut().coulomb_laws = chosen.laws.clone();
        }
    }
    let trials = search.trials(&model)?;
    let predictions: Vec<Prediction> = trials.iter().map(Trial::prediction).collect();
    let best =
        best_predicting(&predictions, search.equal(&predictions), Prefer::Widest).ok_or(DiagnoseError::Singular)?;
    let (cutoff, mut reasons, mut warnings) = match options.preprocess.cutoff_hz {
        None => (trials[best].cutoff_hz, vec![search.explain(&trials, best)], vec![]),
        Some(user) => (user, vec![Choice::CutoffGiven { cutoff_hz: user }], search.compare_user(&trials, best, user)),
    };
    let friction = match options.preprocess.friction_cutoff_hz {
        Some(user) => (user, Choice::FrictionCutoff { cutoff_hz: user, given: true, at_most_quarter: false }),
        None => {
            let chosen = velocity_resolved_cutoff(&positions, cutoff, order).map_err(training)?;
            (chosen.cutoff_hz, chosen.reason)
        }
    };
    reasons.push(friction.1);
    let band = Band { cutoff_hz: cutoff, friction_hz: friction.0 };
    let good = as_good_as_best(&predictions, search.equal(&predictions));
    let narrowest_hz = (0..trials.len()).filter(|&i| good[i]).map(|i| trials[i].cutoff_hz).fold(cutoff, f64::min);
    let narrowest = Band { cutoff_hz: narrowest_hz, friction_hz: search.friction_at(narrowest_hz)? };
    if choose_laws {
        laws = search.laws(&model, band)?;
    }
    if let Some(chosen) = &laws {
        reasons.push(chosen.reason.clone());
    }
    warnings.extend(search.warning.clone());
    Ok(BandChoice { band, reasons, warnings, narrowest, laws })
}

/// One candidate cut-off: how its declared model fits its own filtered torque and predicts the
/// held-out unfiltered torque.
struct Trial {
    cutoff_hz: f64,
    errors: Vec<f64>,
    fp: f64,
    training_fp: f64,
}

impl Trial {
    fn prediction(&self) -> Prediction<'_> {
        Prediction { cutoff_hz: self.cutoff_hz, errors: &self.errors, fp: self.fp, training_fp: self.training_fp }
    }
}

/// What every candidate shares: the logs, the grid, and the samples every candidate is fitted
/// and scored at (clear of the lowest candidate's filter transients and held-out guards, so that
/// all are judged alike).
struct Search<'a> {
    base: &'a BaseParameters,
    train: Log<'a>,
    /// The training log's positions at its step, read once: what each law choice finds stops in.
    raw: RawPositions<'a>,
    validation: Option<Runs<'a>>,
    options: &'a DiagnoseOptions,
    positions: &'a Positions<'a>,
    grid: Vec<f64>,
    /// The widest candidate, with its friction velocity: where the laws are first chosen.
    top: Band,
    fit_rows: Vec<usize>,
    /// Scored samples: of the validation runs, or of the training log's odd blocks.
    scored_rows: Vec<usize>,
    /// The time the scored samples stand for (s).
    scored_s: f64,
    /// The largest alignment shift tried (samples): none when delay is not searched.
    max_shift: isize,
    /// A doubt about the search the report should carry (a band at the edge of what was tried).
    warning: Option<Concern>,
}

impl<'a> Search<'a> {
    fn new(
        model: &Model,
        base: &'a BaseParameters,
        train: Log<'a>,
        validation: Option<&'a Runs<'a>>,
        options: &'a DiagnoseOptions,
        positions: &'a Positions<'a>,
    ) -> Result<Self, DiagnoseError> {
        let (dof, fs) = (model.dof(), positions.fs);
        let train = first(train, dof, MOST_SEARCHED);
        let raw = RawPositions::of(train, dof).map_err(DiagnoseError::Training)?;
        let validation = validation.map(|v| Runs {
            log: first(v.log, dof, MOST_SEARCHED),
            starts: &v.starts[..v.starts.partition_point(|&s| s < MOST_SEARCHED)],
        });
        let order = options.preprocess.order;
        let samples = train.t.len();
        let duration_s = samples as f64 / fs;
        // Identification's range: from where the filter would bend the motion to well above the
        // spectrum's cut-off (the torque holds the motion's products and a closed loop's fast
        // response), and at least to the diagnosis's former band, within a fifth of the rate.
        let spectral = positions.bandwidth_hz.map(|b| CUTOFF_PER_BANDWIDTH * b);
        let top = spectral.map_or(DIAGNOSIS_CUTOFF_HZ, |s| (SEARCH_ABOVE_SPECTRAL * s).max(DIAGNOSIS_CUTOFF_HZ));
        let top = top.min(DIAGNOSIS_CUTOFF_SHARE * fs);
        // Each log must keep enough samples clear of its filter transients: the shortest decides.
        let shortest = validation.as_ref().map_or(samples, |v| samples.min(v.log.t.len()));
        let motion_floor = motion_floor_hz(positions.bandwidth_hz, false)
            .max(edge_limited_cutoff_hz(shortest, fs, false))
            .max(lowest_kept_cutoff_hz(shortest, fs, options.max_delay_s));
        // Ten held-out blocks of at least BLOCK_MEMORIES memories each: the memory scales as the
        // cut-off's period, so the log's length sets the lowest cut-off they fit at.
        let memory_periods = Butterworth::lowpass(order, 0.1 * fs, fs).map_err(training)?.memory_s(fs) * 0.1 * fs;
        let blocks_floor = match validation {
            Some(_) => 0.0,
            None => BLOCK_MEMORIES * MIN_HELDOUT_BLOCKS as f64 * memory_periods / duration_s,
        };
        let floor = motion_floor.max(blocks_floor);
        if floor > top {
            let needed_s = duration_s * floor / top;
            return Err(DiagnoseError::TooShortForBand { duration_s, needed_s, top_hz: top, lowest_hz: floor });
        }
        // Stepped down from the top, so that the widest band searched is a candidate.
        let mut grid: Vec<f64> = geometric_grid(floor, top).iter().rev().map(|g| floor * top / g).collect();
        if let Some(user) = options.preprocess.cutoff_hz {
            grid.push(user);
            grid.sort_by(f64::total_cmp);
        }
        let lowest = grid[0];
        let friction = velocity_resolved_cutoff(positions, top, order).map_err(training)?.cutoff_hz;
        // The samples the lowest candidate keeps (its transients are the longest), at the widest
        // candidate's spacing, thinned to what the fits need.
        let reference = filtered(train, model.dof(), options, Band { cutoff_hz: lowest, friction_hz: lowest })
            .map_err(DiagnoseError::Training)?;
        let margin = options.max_delay_s;
        let kept = kept_samples(&reference, margin, &[], stride(options, fs, top)).map_err(DiagnoseError::Training)?;
        let memory = Butterworth::lowpass(order, lowest, fs).map_err(training)?.memory_s(fs);
        let (fit_rows, scored_rows) = match &validation {
            Some(runs) => {
                let held = filtered(runs.log, model.dof(), options, Band { cutoff_hz: lowest, friction_hz: lowest })
                    .map_err(DiagnoseError::Validation)?;
                let scored = kept_samples(&held, margin, runs.starts, stride(options, fs, top))
                    .map_err(DiagnoseError::Validation)?;
                (thin(kept, MOST_FITTED), thin(scored, MOST_SCORED))
            }
            None => {
                let split = heldout_split(&kept, fs, options.block_s, memory);
                let Split { train, test, .. } = &split;
                let pick =
                    |mask: &[bool]| kept.iter().zip(mask).filter(|(_, m)| **m).map(|(k, _)| *k).collect::<Vec<_>>();
                (thin(pick(train), MOST_FITTED), thin(pick(test), MOST_SCORED))
            }
        };
        let spacing = match scored_rows.as_slice() {
            [first, .., last] => (last - first) as f64 / (scored_rows.len() - 1) as f64,
            _ => 1.0,
        };
        let scored_s = scored_rows.len() as f64 * spacing / fs;
        let warning = (floor == blocks_floor && blocks_floor > motion_floor).then_some(Concern::BandFloorFromLength {
            floor_hz: floor,
            duration_s,
            blocks: MIN_HELDOUT_BLOCKS,
            memories: BLOCK_MEMORIES,
        });
        Ok(Self {
            base,
            train,
            raw,
            validation,
            options,
            positions,
            grid,
            top: Band { cutoff_hz: top, friction_hz: friction },
            fit_rows,
            scored_rows,
            scored_s,
            max_shift: match options.searches(EffectKind::Delay) {
                true => (options.max_delay_s * fs).round() as isize,
                false => 0,
            },
            warning,
        })
    }

    /// The trials of the grid, coarse to fine: every other cut-off first (half an octave apart),
    /// then those between the best of them and its neighbours, and the one above the widest that
    /// predicts as well. The prediction changes slowly with the cut-off, and half the trials find
    /// the same band on a long log in half the time.
    fn trials(&self, model: &Model) -> Result<Vec<Trial>, DiagnoseError> {
        let user = self.options.preprocess.cutoff_hz;
        let last = self.grid.len() - 1;
        let mut done: Vec<Option<Trial>> = (0..self.grid.len()).map(|_| None).collect();
        let mut tried = vec![false; self.grid.len()];
        // The alignment, found at the widest candidate, serves every other.
        let widest = self.trial(model, self.grid[last], -self.max_shift..=self.max_shift)?;
        let shift = widest.as_ref().map_or(0, |(_, s)| *s);
        done[last] = widest.map(|(t, _)| t);
        tried[last] = true;
        // Those of `indices` not yet tried, side by side: each trial is independent of the others.
        let mut run = |indices: Vec<usize>, done: &mut Vec<Option<Trial>>| -> Result<(), DiagnoseError> {
            let mut fresh = Vec::new();
            for i in indices {
                if !tried[i] {
                    tried[i] = true;
                    fresh.push(i);
                }
            }
            let trials = crate::parallel::map(fresh.clone(), |i| self.trial(model, self.grid[i], shift..=shift));
            for (i, trial) in fresh.into_iter().zip(trials) {
                done[i] = trial?.map(|(t, _)| t);
            }
            Ok(())
        };
        // The widest, every other one below it, and the user's.
        run(
            (0..=last).rev().step_by(2).chain((0..=last).filter(|&i| Some(self.grid[i]) == user)).collect(),
            &mut done,
        )?;
        let indices: Vec<usize> = (0..=last).filter(|&i| done[i].is_some()).collect();
        let predictions: Vec<Prediction> =
            indices.iter().filter_map(|&i| done[i].as_ref()).map(Trial::prediction).collect();
        // Around the widest that predicts as well as the best, and around the best.
        let widest = best_predicting(&predictions, self.equal(&predictions), Prefer::Widest).map(|p| indices[p]);
        let most = predictions.iter().enumerate().max_by(|a, b| a.1.fp.total_cmp(&b.1.fp)).map(|(p, _)| indices[p]);
        let around = [widest, most].into_iter().flatten().flat_map(|i| [i.saturating_sub(1), (i + 1).min(last)]);
        run(around.collect(), &mut done)?;
        Ok(done.into_iter().flatten().collect())
    }

    /// Equal predictions: within the best's sampling error, over the independent samples its
    /// residual holds on the scored samples (two per period of its cut-off).
    fn equal(&self, predictions: &[Prediction]) -> Equal {
        let best = predictions.iter().max_by(|a, b| a.fp.total_cmp(&b.fp)).map_or(0.0, |p| p.cutoff_hz);
        Equal::Sampling { independent: (2.0 * best * self.scored_s).min(self.scored_rows.len() as f64) }
    }

    /// The friction velocity's cut-off at band `cutoff`: the user's, or the band's slowed where
    /// the encoders' steps would blur it.
    fn friction_at(&self, cutoff: f64) -> Result<f64, DiagnoseError> {
        match self.options.preprocess.friction_cutoff_hz {
            Some(f) => Ok(f),
            None => {
                let order = self.options.preprocess.order;
                Ok(velocity_resolved_cutoff(self.positions, cutoff, order).map_err(training)?.cutoff_hz)
            }
        }
    }

    /// Each joint's Coulomb law fitted in `band` on the part of the training log the band is
    /// chosen on: a law is a matter of the joint's friction, which a minute at 1 kHz shows as
    /// well as five (the law choice fits 10,000 samples of either, spread over it), and the choice,
    /// which filters every candidate's column over all it is given, costs no more on a longer log.
    fn laws(&self, model: &Model, band: Band) -> Result<Option<ChosenLaws>, DiagnoseError> {
        let pre = filtered(self.train, model.dof(), self.options, band).map_err(DiagnoseError::Training)?;
        laws_for_fit(model, self.base, &pre, self.raw).map_err(DiagnoseError::Training)
    }

    /// The declared model fitted at `cutoff` on the fitted samples, and its prediction of the
    /// unfiltered held-out torque, with the torque shifted by each of `shifts` samples against the
    /// positions and the best kept; `None` when it cannot be fitted there. The shift that aligns
    /// the log is found once, at the widest candidate ([`Self::trials`]), as the diagnosis
    /// aligns a log before anything else: a misaligned log predicts worse the wider its band, and
    /// would otherwise narrow the band until the delay no longer shows.
    fn trial(
        &self,
        model: &Model,
        cutoff: f64,
        shifts: std::ops::RangeInclusive<isize>,
    ) -> Result<Option<(Trial, isize)>, DiagnoseError> {
        let dof = model.dof();
        let band = Band { cutoff_hz: cutoff, friction_hz: self.friction_at(cutoff)? };
        let pre = filtered(self.train, dof, self.options, band).map_err(DiagnoseError::Training)?;
        let (fit_columns, _) = declared_columns(model, self.base, &pre, &self.fit_rows);
        let tau_fit = shifted_rows(&pre.tau, dof, &self.fit_rows, 0);
        let weights: Vec<f64> = (0..dof).map(|k| 1.0 / rms(&tau_fit, dof, k).max(f64::MIN_POSITIVE)).collect();
        let fit_columns: Vec<Column> = fit_columns
            .into_iter()
            .map(|mut c| {
                c.scale_rows(&weights);
                c
            })
            .collect();
        let refs: Vec<&Column> = fit_columns.iter().collect();
        let gram = gram(&refs, dof, Rows::All);
        let held_pre = match &self.validation {
            Some(runs) => Some(filtered(runs.log, dof, self.options, band).map_err(DiagnoseError::Validation)?),
            None => None,
        };
        let held = self.validation.as_ref().map_or(self.train, |runs| runs.log);
        let columns = unfiltered_columns(model, self.base, held_pre.as_ref().unwrap_or(&pre), &self.scored_rows);
        let predictors: Vec<&Column> = columns.iter().collect();
        let mut best: Option<(Trial, isize)> = None;
        for shift in shifts {
            let tau_shifted = shifted_rows(&pre.tau, dof, &self.fit_rows, shift);
            let y: Vec<f64> = tau_shifted.iter().enumerate().map(|(i, t)| t * weights[i % dof]).collect();
            let Some(beta) = solve_scaled(&gram, &rhs(&refs, &y, dof, Rows::All)) else { return Ok(None) };
            let predicted = predict(&predictors, &beta, dof, self.scored_rows.len(), &vec![1.0; dof]);
            let measured = shifted_rows(held.tau, dof, &self.scored_rows, shift);
            let fp = mean(&joint_metrics(&measured, &predicted, dof).fp_percent);
            if best.as_ref().is_some_and(|(b, _)| b.fp >= fp) {
                continue;
            }
            let variances: Vec<f64> =
                (0..dof).map(|k| rms_about_mean(&measured, dof, k).powi(2).max(f64::MIN_POSITIVE)).collect();
            let errors = measured
                .chunks(dof)
                .zip(predicted.chunks(dof))
                .map(|(m, p)| (0..dof).map(|k| (m[k] - p[k]).powi(2) / variances[k]).sum())
                .collect();
            let fitted = predict(&refs, &beta, dof, tau_shifted.len() / dof, &weights);
            let training_fp = mean(&joint_metrics(&tau_shifted, &fitted, dof).fp_percent);
            best = Some((Trial { cutoff_hz: cutoff, errors, fp, training_fp }, shift));
        }
        Ok(best)
    }

    /// The reason of the chosen cut-off.
    fn explain(&self, trials: &[Trial], best: usize) -> Choice {
        let predictions: Vec<Prediction> = trials.iter().map(Trial::prediction).collect();
        let good = as_good_as_best(&predictions, self.equal(&predictions));
        let most = (0..trials.len()).max_by(|&a, &b| trials[a].fp.total_cmp(&trials[b].fp)).unwrap_or(best);
        Choice::BandSearched {
            cutoff_hz: trials[best].cutoff_hz,
            trials: trials.iter().map(|t| [t.cutoff_hz, t.fp]).collect(),
            validation_runs: self.validation.is_some(),
            most_accurate_hz: trials[most].cutoff_hz,
            most_accurate_fp: trials[most].fp,
            sigmas: EQUAL_PREDICTION_SIGMAS,
            equal_hz: (0..trials.len()).filter(|&i| good[i]).map(|i| trials[i].cutoff_hz).collect(),
        }
    }

    /// A warning when the user's cut-off predicts held-out torque worse than the data's choice.
    fn compare_user(&self, trials: &[Trial], best: usize, user: f64) -> Vec<Concern> {
        let predictions: Vec<Prediction> = trials.iter().map(Trial::prediction).collect();
        let good = as_good_as_best(&predictions, self.equal(&predictions));
        let Some(at) = trials.iter().position(|t| t.cutoff_hz == user) else { return vec![] };
        if good[at] {
            return vec![];
        }
        vec![Concern::CutoffGivenPredictsWorse {
            cutoff_hz: user,
            chosen_hz: trials[best].cutoff_hz,
            sigmas: EQUAL_PREDICTION_SIGMAS,
            fp: trials[at].fp,
            chosen_fp: trials[best].fp,
        }]
    }
}

/// A filter that cannot be built on the training log, as the error the diagnosis reports.
fn training(e: impl Into<PreprocessError>) -> DiagnoseError {
    DiagnoseError::Training(e.into())
}

/// The declared columns at `rows` of `pre` with the Coulomb columns unfiltered (each joint's law
/// of the friction velocity), as a prediction of the unfiltered torque needs them.
fn unfiltered_columns(model: &Model, base: &BaseParameters, pre: &Preprocessed, rows: &[usize]) -> Vec<Column> {
    let dof = model.dof();
    let (mut columns, _) = declared_columns(model, base, pre, rows);
    let directions = pre.friction.directions(&model.coulomb_laws);
    for (c, &j) in base.independent.iter().enumerate() {
        if let Some(k) = (0..dof).find(|&k| model.layout().coulomb(k) == j) {
            let values = rows.iter().map(|&s| directions[s * dof + k]).collect();
            columns[c] = Column::Joint(k, values);
        }
    }
    columns
}

/// `Σ β_i c_i` over `samples` rows, divided back by the joint weights.
fn predict(columns: &[&Column], beta: &[f64], dof: usize, samples: usize, weights: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; samples * dof];
    for (c, b) in columns.iter().zip(beta) {
        super::regression::axpy(&mut out, *b, c, dof);
    }
    out.iter_mut().enumerate().for_each(|(i, v)| *v /= weights[i % dof]);
    out
}

/// The first `most` samples of `log`.
fn first(log: Log, dof: usize, most: usize) -> Log {
    let n = log.t.len().min(most);
    Log { t: &log.t[..n], q: &log.q[..n * dof], tau: &log.tau[..n * dof] }
}

/// Every `step`-th of `rows`, at most `most` of them.
fn thin(rows: Vec<usize>, most: usize) -> Vec<usize> {
    let step = rows.len().div_ceil(most).max(1);
    rows.into_iter().step_by(step).collect()
}

/// The rows `rows` of a `samples × dof` signal, each taken `shift` samples later.
fn shifted_rows(x: &[f64], dof: usize, rows: &[usize], shift: isize) -> Vec<f64> {
    rows.iter()
        .map(|&s| (s as isize + shift) as usize)
        .flat_map(|s| x[s * dof..(s + 1) * dof].iter().copied())
        .collect()
}

fn rms(x: &[f64], dof: usize, k: usize) -> f64 {
    let n = (x.len() / dof).max(1);
    (x.iter().skip(k).step_by(dof).map(|v| v * v).sum::<f64>() / n as f64).sqrt()
}

fn rms_about_mean(x: &[f64], dof: usize, k: usize) -> f64 {
    let n = (x.len() / dof).max(1) as f64;
    let mean = x.iter().skip(k).step_by(dof).sum::<f64>() / n;
    (x.iter().skip(k).step_by(dof).map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len().max(1) as f64
}
