//! Each joint's Coulomb law chosen from the data: how its dry friction rises through zero speed.
//!
//! `sign(q̇)` says the friction is at its full value at any speed. Real joints rarely do that: a
//! harmonic drive's or a cable's friction rises over a speed of its own, and a joint that only
//! ever moves slowly through a reversal shows that rise in its torque. Fitted with `sign(q̇)`,
//! that shortfall near zero speed is left in the residual, where it reads as a Stribeck term of
//! the wrong sign (less friction near zero, not more), as hysteresis or as a cable's compliance
//! (issue 44: most joints of three real robots). So each joint's law is `tanh(q̇/v)` with its
//! *friction velocity* v, or `sign(q̇)` (v → 0), chosen by prediction: the law whose fit, the
//! other columns refitted, best predicts stretches of the log it was not fitted on
//! ([`LAW_FOLDS`]-fold cross-validation), kept over `sign(q̇)` only where it predicts better by
//! more than one standard error ([`LAW_STANDARD_ERRORS`]). One nonlinear parameter per joint,
//! searched over a grid of [`FRICTION_VELOCITY_SHARES`] of the joint's RMS speed, one joint at a
//! time ([`LAW_SWEEPS`] passes over the joints).
//!
//! Prediction, not the fit's own error, because a law slow enough to stay unsaturated over most of
//! the motion trades against viscous friction: in-sample it also soaks up what the model lacks,
//! and its coefficients then fail on motion they were not fitted to. Held-out stretches keep the
//! law that the motion itself pins down (a closed loop whose insertion rarely moves faster than
//! twice its friction velocity, docs/identification.md) and refuse the one that only fits.
//!
//! Identification and the diagnosis both call [`choose_laws`] when the robot declares no law
//! ([`crate::model::CoulombLaws::is_declared`]); the model file keeps the result, and the
//! controllers' friction compensation and the diagnosis against that file use it.

use super::estimate::{coulomb_positions, regressor_rows};
use super::log::Log;
use super::preprocess::{validate_log, PreprocessError, Preprocessed};
use crate::base_parameters::BaseParameters;
use crate::choices::{Choice, JointLaw, UnresolvedLaw};
use crate::dense::{self, dot, Unseen};
use crate::effects::FRICTION_VELOCITY_SHARES;
use crate::model::{CoulombLaws, CoulombShape, Model};
use crate::signal::filter::{Butterworth, FilterError};
use crate::signal::friction::RawVelocity;
use crate::signal::resting::{arrange, stopped_in_log};
use faer::Mat;
use std::collections::HashMap;
use std::ops::Range;

/// Contiguous stretches of the log, at most, each predicted by the fit on the others (fewer where
/// the filter's memory asks for longer ones: `fold_count`). The paired fold-by-fold differences
/// give the standard error [`LAW_STANDARD_ERRORS`] is counted in. (Two standard errors, as the
/// cut-offs' rule asks, kept `sign(q̇)` on every joint of the TX40, whose diagnosis then found
/// Stribeck terms of the wrong sign on four joints, the symptom of issue 44.)
pub const LAW_FOLDS: usize = 10;

/// Passes over the joints: each joint's law is chosen with the others' as they stand, and a
/// second pass lets each see the others' choices. The Coulomb columns of different joints share
/// no rows, so a third pass has not changed a choice on any log tried (docs/identification.md).
pub const LAW_SWEEPS: usize = 2;

/// A stacked least-squares problem whose Coulomb columns are to be chosen: the columns (each
/// `samples × dof`, rows sample by sample, joint by joint, weighted as the fit weighs them), the
/// target alike, and where each joint's Coulomb column sits among them.
pub struct LawProblem {
    pub columns: Vec<Vec<f64>>,
    pub y: Vec<f64>,
    pub dof: usize,
    /// `(joint, column)` for every joint whose Coulomb column is fitted.
    pub coulomb: Vec<(usize, usize)>,
    /// Each joint's row weight, applied to its candidate columns.
    pub weights: Vec<f64>,
    /// Samples at each end of a fold that are not scored: filtering spreads a sample's noise over
    /// its neighbours, and a scored sample that close to the fitted ones would share their noise.
    pub guard: usize,
}

/// The laws chosen, and what chose them.
#[derive(Clone, Debug)]
pub struct ChosenLaws {
    pub laws: CoulombLaws,
    /// Per joint with a Coulomb column: each candidate's law and its held-out weighted squared
    /// error over the error with `sign(q̇)`, at the last pass.
    pub scores: Vec<(usize, Vec<(CoulombShape, f64)>)>,
    pub reason: Choice,
}

/// The candidate laws of a joint whose RMS speed (filtered, as the friction velocity is) is
/// `rms_speed`: `sign(q̇)`, then `tanh(q̇/v)` for every share.
pub fn candidate_laws(rms_speed: f64) -> Vec<CoulombShape> {
    let smooth = FRICTION_VELOCITY_SHARES.iter().filter_map(|s| CoulombShape::tanh(s * rms_speed));
    std::iter::once(CoulombShape::Sign).chain(smooth).collect()
}

/// Each joint's law: the candidate ([`candidate_laws`] of `rms_speed[k]`) whose fit, every other
/// column refitted, predicts the held-out folds best.
/// `columns(k, laws)` gives joint `k`'s Coulomb column under each of `laws` at the problem's
/// samples, unweighted, as the fit filters them (several at a time: a filter runs
/// [`crate::signal::filter::LANES`] columns side by side for the time of one); `start` are the laws the
/// problem's columns hold. Joints without a Coulomb column keep theirs.
pub fn choose_laws<E>(
    mut problem: LawProblem,
    rms_speed: &[f64],
    start: &CoulombLaws,
    columns: impl Fn(usize, &[CoulombShape]) -> Result<Vec<Vec<f64>>, E>,
    resolves: impl Fn(usize, f64) -> Resolution,
) -> Result<ChosenLaws, E> {
    let mut shapes: Vec<CoulombShape> = start.shapes().to_vec();
    let samples = problem.y.len() / problem.dof.max(1);
    let fold_total = fold_count(samples, problem.guard);
    if fold_total < LAW_MIN_FOLDS {
        let reason = Choice::LawsKept {
            velocities: shapes.iter().map(|s| s.epsilon()).collect(),
            samples,
            folds: fold_total,
            guards_per_fold: GUARDS_PER_FOLD,
            guard: problem.guard,
            min_folds: LAW_MIN_FOLDS,
        };
        return Ok(ChosenLaws { laws: CoulombLaws::declared(shapes), scores: Vec::new(), reason });
    }
    // Each Coulomb joint's candidate laws, their weighted columns filtered together.
    let grids: Vec<Vec<CoulombShape>> = problem.coulomb.iter().map(|&(k, _)| candidate_laws(rms_speed[k])).collect();
    let mut cache = ColumnCache { columns, weights: problem.weights.clone(), kept: HashMap::new() };
    for (&(k, _), laws) in problem.coulomb.iter().zip(&grids) {
        cache.fetch(k, laws)?;
    }
    let mut folds = Folds::of(&problem, fold_total);
    let mut scores = Vec::new();
    let mut unresolved = Vec::new();
    for sweep in 0..LAW_SWEEPS {
        let coulomb = problem.coulomb.clone();
        for (&(k, c), laws) in coulomb.iter().zip(&grids) {
            let predicted: Vec<Option<Vec<f64>>> = laws
                .iter()
                .map(|law| folds.heldout_errors(&problem, c, JointColumn { joint: k, values: cache.get(k, *law) }))
                .collect();
            let total = |e: &Option<Vec<f64>>| e.as_ref().map_or(f64::INFINITY, |e| e.iter().sum::<f64>());
            let errors: Vec<f64> = predicted.iter().map(total).collect();
            let on_grid =
                (0..laws.len()).min_by(|&a, &b| errors[a].total_cmp(&errors[b])).expect("sign is a candidate");
            // Between the grid's neighbours of the best smooth law, to a fraction of a per cent.
            let (fittest_law, fittest_folds) = match on_grid {
                0 => (laws[0], predicted[0].clone()),
                i => {
                    let around = (laws[(i - 1).max(1)], laws[(i + 1).min(laws.len() - 1)]);
                    let error_at = |law: CoulombShape, ahead: &[CoulombShape]| {
                        cache.fetch_with(k, law, ahead)?;
                        Ok(folds.heldout_errors(&problem, c, JointColumn { joint: k, values: cache.get(k, law) }))
                    };
                    refine(around, (laws[i], predicted[i].clone()), error_at)?
                }
            };
            let fittest_error = total(&fittest_folds);
            let resolution = fittest_law.epsilon().map(|v| (v, resolves(k, v)));
            let resolved = resolution.is_none_or(|(v, r)| r.resolves(v));
            // sign(q̇) unless the fittest law predicts better by more than the margin, and is a
            // law of the motion rather than of the filter.
            let law = match resolved && !within_margin(&predicted[0], &fittest_folds) {
                false => laws[0],
                true => fittest_law,
            };
            if sweep + 1 == LAW_SWEEPS && !resolved {
                if let Some((v, r)) = resolution {
                    unresolved.push((k, v, r));
                }
            }
            shapes[k] = law;
            put(&mut problem, c, k, cache.get(k, law));
            folds.replace(&problem, c);
            if sweep + 1 == LAW_SWEEPS {
                let sign = errors[0].max(f64::MIN_POSITIVE);
                let mut score: Vec<(CoulombShape, f64)> =
                    laws.iter().zip(&errors).map(|(law, e)| (*law, e / sign)).collect();
                score.push((fittest_law, fittest_error / sign));
                scores.push((k, score));
            }
        }
    }
    let laws = CoulombLaws::declared(shapes);
    let unresolved = unresolved.into_iter().map(|(joint, velocity, r)| UnresolvedLaw {
        joint,
        velocity,
        stray: r.stray,
        samples: r.samples,
        transition: r.transition,
        needed: r.needed,
    });
    let reason = explain(&laws, &scores, rms_speed, fold_total, unresolved.collect());
    Ok(ChosenLaws { laws, scores, reason })
}

/// Each joint's candidate columns, weighted, by law: the grid's, and those the refinement tried,
/// kept across sweeps, whose refinements mostly retrace each other. Filtering a column over a
/// long log is most of a law's cost, and the filter runs up to [`crate::signal::filter::LANES`] side by
/// side for the time of one, so the columns are made several at a time.
struct ColumnCache<F> {
    columns: F,
    weights: Vec<f64>,
    kept: HashMap<(usize, Option<u64>), Vec<f64>>,
}

impl<F, E> ColumnCache<F>
where
    F: Fn(usize, &[CoulombShape]) -> Result<Vec<Vec<f64>>, E>,
{
    fn key(k: usize, law: CoulombShape) -> (usize, Option<u64>) {
        (k, law.epsilon().map(f64::to_bits))
    }

    /// Joint `k`'s columns of those of `laws` not yet made, made together.
    fn fetch(&mut self, k: usize, laws: &[CoulombShape]) -> Result<(), E> {
        let mut missing: Vec<CoulombShape> = Vec::new();
        for &law in laws {
            if !self.kept.contains_key(&Self::key(k, law)) && !missing.contains(&law) {
                missing.push(law);
            }
        }
        if missing.is_empty() {
            return Ok(());
        }
        for (law, values) in missing.iter().zip((self.columns)(k, &missing)?) {
            self.kept.insert(Self::key(k, *law), weighted(values, self.weights[k]));
        }
        Ok(())
    }

    /// Joint `k`'s column of `law`, made, when it is not yet, with those of `ahead` (the laws a
    /// search may ask for next) in the same filtering.
    fn fetch_with(&mut self, k: usize, law: CoulombShape, ahead: &[CoulombShape]) -> Result<(), E> {
        if self.kept.contains_key(&Self::key(k, law)) {
            return Ok(());
        }
        let laws: Vec<CoulombShape> = std::iter::once(law).chain(ahead.iter().copied()).collect();
        self.fetch(k, &laws)
    }

    fn get(&self, k: usize, law: CoulombShape) -> &[f64] {
        self.kept.get(&Self::key(k, law)).expect("a law's column is fetched before it is read")
    }
}

/// Where a smooth law acts: the moving samples whose velocity is below this many times the law's
/// v (tanh(3) = 0.995: faster, the law is sign(q̇) to half a per cent).
pub const LAW_ACTS_BELOW: f64 = 3.0;

/// How far a joint's friction velocity (the velocity its Coulomb column switches with), filtered
/// below the main cut-off, strays from the velocity at the main cut-off where a law of friction
/// velocity v acts: the RMS of their difference over the moving samples where either velocity is
/// below [`LAW_ACTS_BELOW`]·v. There the law's column leaves sign(q̇)'s (the friction velocity is
/// slow), or the motion is in the law's transition (the velocity at the main cut-off is): its
/// shape is read from both, and both must agree to within v.
///
/// And how many samples show the law at all: where it acts, the joint neither resting nor near a
/// stop ([`stopped_in_log`], widened). A transition that lies within rests and stops is not seen:
/// the joint's friction there is whatever holds it, under a sign law as under a smooth one, and
/// the filtered rows beside them show the filter's ramp through that holding friction, which a
/// smooth law of the filtered velocity imitates whatever the joint's law. With fewer than
/// [`LAW_TRANSITION_GUARDS`] filter memories of such samples, `sign(q̇)`, the simpler law, stays
/// (docs/identification.md, "Fresh seeds, and a second loop").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolution {
    pub stray: f64,
    pub samples: usize,
    /// Samples where the law acts, clear of rests and stops.
    pub transition: usize,
    /// The fewest such samples that show a law: [`LAW_TRANSITION_GUARDS`] filter memories.
    pub needed: usize,
}

/// Filter memories' worth of samples, in the law's transition and clear of rests and stops, that
/// a smooth law needs to be told from `sign(q̇)`: as many as one fold leaves unscored at its two
/// ends and one more.
pub const LAW_TRANSITION_GUARDS: usize = 3;

impl Resolution {
    /// Nothing strays and no sample is asked for: a law resolved whatever it is (the choice's
    /// own tests).
    pub const EXACT: Resolution = Resolution { stray: 0.0, samples: 0, transition: 0, needed: 0 };

    /// Whether a law of friction velocity `v` is told apart from sign(q̇) on this velocity. A
    /// friction velocity filtered well below the motion's band moves slowly into and out of every
    /// rest, and a law narrower than that drift fits the filter's passage through zero, not the
    /// joint's friction: its coefficients do not carry over to the true velocity
    /// (docs/identification.md, "A sign-law closed loop").
    pub fn resolves(&self, v: f64) -> bool {
        self.stray <= v && self.transition >= self.needed
    }

    /// Joint `k`'s resolution of a law of friction velocity `v` in `data`, over its settled
    /// samples: `stopped` are those near a stop ([`stopped_in_log`], widened), `memory` the
    /// torque filter's memory in samples.
    pub fn of(data: &Preprocessed, stopped: &[bool], k: usize, v: f64, memory: usize) -> Self {
        // A friction velocity filtered at or above the main cut-off is the wider-band of the two,
        // the closer to the motion's own: nothing strays.
        let strays = data.friction_cutoff_hz < data.cutoff_hz;
        let dof = data.dof;
        let (mut sum, mut samples, mut transition) = (0.0, 0, 0);
        for i in data.settled.clone().map(|s| s * dof + k) {
            let slow = data.qd_friction[i].abs().min(data.qd[i].abs()) < LAW_ACTS_BELOW * v;
            if !data.resting[i] && slow {
                if strays {
                    sum += (data.qd_friction[i] - data.qd[i]).powi(2);
                }
                samples += 1;
                transition += usize::from(!stopped[i]);
            }
        }
        let stray = if samples > 0 { (sum / samples as f64).sqrt() } else { 0.0 };
        Self { stray, samples, transition, needed: LAW_TRANSITION_GUARDS * memory }
    }
}

/// Standard errors by which the best smooth law must predict better than `sign(q̇)` to be kept:
/// the one-standard-error rule of cross-validation (Breiman et al. 1984; Hastie, Tibshirani and
/// Friedman, *Elements of Statistical Learning* §7.10), `sign(q̇)` being the simpler model (no
/// friction velocity to fit). The least held-out error alone is the best of a grid of noisy
/// scores: on `sign(q̇)` data it kept near-sign laws, and sometimes wide ones, by chance, and the
/// estimates' σ then missed the law's own uncertainty (docs/identification.md §7). Within the
/// smooth laws the friction velocity is the one of least error: it is a parameter of the law,
/// not a rung of complexity.
pub const LAW_STANDARD_ERRORS: f64 = 1.0;

/// [`LAW_STANDARD_ERRORS`] as the same one-sided level of Student's t with `folds − 1` degrees of
/// freedom: a spread from few folds is itself uncertain, and the margin widens to keep the rate at
/// which noise alone clears it.
fn standard_errors(folds: usize) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
    let level = Normal::standard().cdf(LAW_STANDARD_ERRORS);
    StudentsT::new(0.0, 1.0, (folds.max(2) - 1) as f64).map_or(LAW_STANDARD_ERRORS, |t| t.inverse_cdf(level))
}

/// Whether a candidate's held-out errors are within the margin ([`standard_errors`] of the folds)
/// of the fittest's: the standard error of the summed fold-by-fold differences, from their spread.
fn within_margin(candidate: &FoldErrors, fittest: &FoldErrors) -> bool {
    let (Some(candidate), Some(fittest)) = (candidate, fittest) else {
        return candidate.is_some() && fittest.is_none();
    };
    let d: Vec<f64> = candidate.iter().zip(fittest).map(|(a, b)| a - b).collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let spread = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    mean * n <= standard_errors(d.len()) * spread * n.sqrt()
}

/// Laws within this share of each other's friction velocity are the same choice: closer than the
/// refinement resolves, and the fit moves by a fraction of a per cent between them.
pub const SAME_LAW: f64 = 0.02;

/// Whether `next` keeps every joint's law of `previous` (the same kind, friction velocities within
/// [`SAME_LAW`]).
pub fn settled(previous: &CoulombLaws, next: &CoulombLaws) -> bool {
    previous.shapes().iter().zip(next.shapes()).all(|(a, b)| match (a.epsilon(), b.epsilon()) {
        (None, None) => true,
        (Some(x), Some(y)) => (x / y - 1.0).abs() <= SAME_LAW,
        _ => false,
    })
}

/// `next`'s laws where each joint's is of the kind `previous`'s was (smooth in both, whatever its
/// friction velocity, or `sign(q̇)` in both), and `sign(q̇)` on the joints whose kind changed,
/// which are listed. Where rounds of choosing the laws and the cut-offs with each other do not
/// settle, a joint that takes a smooth law in one round and `sign(q̇)` in the next is not shown a
/// law by the data, and `sign(q̇)` is the simpler one; a smooth law whose friction velocity moves
/// with the cut-off is still a smooth law (the TX40's, whose rounds alternate between two cut-offs).
pub fn steady(previous: &CoulombLaws, next: &CoulombLaws) -> (CoulombLaws, Vec<usize>) {
    let mut unsettled = Vec::new();
    let shapes = previous
        .shapes()
        .iter()
        .zip(next.shapes())
        .enumerate()
        .map(|(k, (a, b))| match a.epsilon().is_some() == b.epsilon().is_some() {
            true => *b,
            false => {
                unsettled.push(k);
                CoulombShape::Sign
            }
        })
        .collect();
    (CoulombLaws::declared(shapes), unsettled)
}

/// At most this many samples are fitted per candidate law: evenly spread over a long log, they
/// choose as all of it would, at a bounded cost.
const MOST_FITTED: usize = 10_000;

/// Identification's laws: [`choose_laws`] on the preprocessed log's settled samples (at most
/// `MOST_FITTED` of them), each joint's rows weighted by one over its filtered torque's RMS so
/// that N·m and N do not mix. The non-Coulomb columns are taken unfiltered here (they are smooth;
/// the fit itself filters them) and the Coulomb candidates filtered like the torque, as the fit
/// builds them. `None` when the declared model has no Coulomb column.
pub fn laws_for_fit(
    model: &Model,
    base: &BaseParameters,
    data: &Preprocessed,
    raw: RawPositions,
) -> Result<Option<ChosenLaws>, PreprocessError> {
    let dof = model.dof();
    let columns = &base.independent;
    let positions = coulomb_positions(model, columns);
    if positions.is_empty() {
        return Ok(None);
    }
    let settled = data.settled.clone();
    let step = settled.len().div_ceil(MOST_FITTED).max(1);
    let rows: Vec<usize> = settled.step_by(step).collect();
    let w = regressor_rows(model, data, columns, &rows);
    let rms =
        |x: &[f64], k: usize| (rows.iter().map(|&s| x[s * dof + k].powi(2)).sum::<f64>() / rows.len() as f64).sqrt();
    let weights: Vec<f64> = (0..dof).map(|k| rms(&data.tau, k)).map(|r| if r > 0.0 { 1.0 / r } else { 1.0 }).collect();
    let rms_speed: Vec<f64> = (0..dof).map(|k| rms(&data.qd_friction, k)).collect();
    // A resting joint's rows are left out as the fit leaves them out: zero. So are the rows near
    // a stop, whose friction ramps through the filter as no law of the velocity does.
    let stopped = stops(raw, data)?;
    let resting = |s: usize, k: usize| data.resting[s * dof + k] || stopped[s * dof + k];
    // Each law's directions side by side, filtered together, read at the rows; the laws split
    // between the cores.
    let some_columns = |k: usize, laws: &[CoulombShape]| -> Result<Vec<Vec<f64>>, PreprocessError> {
        let width = laws.len();
        let mut side_by_side = Vec::new();
        for (j, law) in laws.iter().enumerate() {
            let directions = data.friction.joint_directions(k, dof, *law);
            side_by_side.resize(directions.len() * width, 0.0);
            directions.iter().enumerate().for_each(|(s, v)| side_by_side[s * width + j] = *v);
        }
        let filtered = data.filter_like_torque(&side_by_side, width)?;
        let at_rows =
            |j: usize| rows.iter().map(|&s| if resting(s, k) { 0.0 } else { filtered[s * width + j] }).collect();
        Ok((0..width).map(at_rows).collect())
    };
    let columns = |k: usize, laws: &[CoulombShape]| -> Result<Vec<Vec<f64>>, PreprocessError> {
        let parts: Vec<&[CoulombShape]> = laws.chunks(laws.len().div_ceil(crate::parallel::cores()).max(1)).collect();
        let made = crate::parallel::map(parts, |part| some_columns(k, part));
        Ok(made.into_iter().collect::<Result<Vec<_>, _>>()?.into_iter().flatten().collect())
    };
    let kept = |r: usize| if resting(rows[r / dof], r % dof) { 0.0 } else { weights[r % dof] };
    let mut stacked: Vec<Vec<f64>> =
        (0..w.ncols()).map(|c| (0..w.nrows()).map(|r| w[(r, c)] * kept(r)).collect()).collect();
    for &(k, c) in &positions {
        for (s, v) in columns(k, &[model.coulomb_laws.shape(k)])?[0].iter().enumerate() {
            stacked[c][s * dof + k] = v * weights[k];
        }
    }
    let y = rows
        .iter()
        .flat_map(|&s| (0..dof).map(move |k| (s, k)))
        .map(|(s, k)| if resting(s, k) { 0.0 } else { data.tau[s * dof + k] * weights[k] })
        .collect();
    // The torque's filter spreads each sample over its memory, in rows of the thinned samples.
    let memory_s =
        Butterworth::lowpass(data.order, data.cutoff_hz, data.rate_hz()).map_or(0.0, |f| f.memory_s(data.rate_hz()));
    let guard = (memory_s * data.rate_hz() / step as f64).ceil() as usize;
    let problem = LawProblem { columns: stacked, y, dof, coulomb: positions, weights, guard };
    let memory = (memory_s * data.rate_hz()).ceil() as usize;
    let resolves = |k, v| Resolution::of(data, &stopped, k, v, memory);
    choose_laws(problem, &rms_speed, &model.coulomb_laws, columns, resolves).map(Some)
}

/// The positions `data` was preprocessed from, as logged: `N × dof` at a step of `dt` (s).
#[derive(Clone, Copy)]
pub struct RawPositions<'a> {
    pub q: &'a [f64],
    pub dt: f64,
}

impl<'a> RawPositions<'a> {
    /// The positions of `log`, at its step as preprocessing reads it.
    pub fn of(log: Log<'a>, dof: usize) -> Result<Self, PreprocessError> {
        Ok(Self { q: log.q, dt: validate_log(log.t, log.q, log.tau, dof)? })
    }
}

/// Which of `data`'s samples lie near a stop shorter than a rest: [`stopped_in_log`] on the raw
/// positions and their friction velocity at the raw rate, widened by the longer memory of the
/// friction velocity's filter and the torque's, arranged as `data`'s samples are.
fn stops(raw: RawPositions, data: &Preprocessed) -> Result<Vec<bool>, FilterError> {
    let dof = data.dof;
    let velocity = RawVelocity::of_log(raw.q, dof, None, raw.dt).filtered(data.order, data.friction_cutoff_hz, 1)?;
    let friction = Butterworth::lowpass(data.order, data.friction_cutoff_hz, 1.0 / raw.dt)?;
    let torque = Butterworth::lowpass(data.order, data.cutoff_hz, data.sample_rate_hz)?;
    let memory_s = friction.memory_s(1.0 / raw.dt).max(torque.memory_s(data.sample_rate_hz));
    let widen = (memory_s / raw.dt).ceil() as usize;
    let stopped = stopped_in_log(raw.q, &velocity.mean(), dof, raw.dt, widen);
    Ok(arrange(stopped, dof, data.averaging(), data.decimate))
}

/// Golden-section steps that refine a friction velocity between its grid neighbours: the bracket,
/// a factor of about 4.8, shrinks to within 0.3 % of the best.
const REFINE_STEPS: usize = 14;

/// Each fold's held-out error of a candidate, `None` where its fit could not be solved.
type FoldErrors = Option<Vec<f64>>;

/// A golden-section bracket in log v: `a < x1 < x2 < b`.
#[derive(Clone, Copy)]
struct Bracket {
    a: f64,
    b: f64,
    x1: f64,
    x2: f64,
}

impl Bracket {
    const RATIO: f64 = 0.618_033_988_749_894_9;

    fn new(a: f64, b: f64) -> Self {
        Self { a, b, x1: b - Self::RATIO * (b - a), x2: a + Self::RATIO * (b - a) }
    }

    /// The bracket narrowed to the side of the better interior point (`x1`'s when `lower`), and
    /// the point it must evaluate next.
    fn narrowed(self, lower: bool) -> (Self, f64) {
        let Self { a, b, x1, x2 } = self;
        match lower {
            true => {
                let x = x2 - Self::RATIO * (x2 - a);
                (Self { a, b: x2, x1: x, x2: x1 }, x)
            }
            false => {
                let x = x1 + Self::RATIO * (b - x1);
                (Self { a: x1, b, x1: x2, x2: x }, x)
            }
        }
    }
}

/// The law of least held-out error between the two laws of `around` (both smooth), starting
/// from `best` (its law and errors): a golden-section search in log v, `error_at(law, ahead)`
/// giving a law's errors, and told the laws the search may ask for next, so that their columns
/// are filtered with its own (both points the next step could need: two steps per filtering).
/// Returns the law and its errors.
fn refine<E>(
    around: (CoulombShape, CoulombShape),
    best: (CoulombShape, FoldErrors),
    mut error_at: impl FnMut(CoulombShape, &[CoulombShape]) -> Result<FoldErrors, E>,
) -> Result<(CoulombShape, FoldErrors), E> {
    let total = |e: &FoldErrors| e.as_ref().map_or(f64::INFINITY, |e| e.iter().sum::<f64>());
    let log_v = |law: CoulombShape| law.epsilon().map_or(f64::NEG_INFINITY, f64::ln);
    let law_at = |x: f64| CoulombShape::Tanh { epsilon: x.exp() };
    let ahead = |b: Bracket| [law_at(b.narrowed(true).1), law_at(b.narrowed(false).1)];
    let mut bracket = Bracket::new(log_v(around.0), log_v(around.1));
    let [lower, upper] = ahead(bracket);
    let mut f1 = error_at(law_at(bracket.x1), &[law_at(bracket.x2), lower, upper])?;
    let mut f2 = error_at(law_at(bracket.x2), &[])?;
    for step in 0..REFINE_STEPS {
        let lower = total(&f1) <= total(&f2);
        let (next, x) = bracket.narrowed(lower);
        let f = match step + 1 < REFINE_STEPS {
            true => error_at(law_at(x), &ahead(next))?,
            false => error_at(law_at(x), &[])?,
        };
        (f1, f2) = match lower {
            true => (f, f1),
            false => (f2, f),
        };
        bracket = next;
    }
    let (x, errors) = if total(&f1) <= total(&f2) { (bracket.x1, f1) } else { (bracket.x2, f2) };
    Ok(match total(&errors) <= total(&best.1) {
        true => (law_at(x), errors),
        false => best,
    })
}

/// Joint `k`'s rows of column `c` set to `values`.
fn put(problem: &mut LawProblem, c: usize, k: usize, values: &[f64]) {
    for (s, v) in values.iter().enumerate() {
        problem.columns[c][s * problem.dof + k] = *v;
    }
}

/// `values` (one joint's rows) times its row weight.
fn weighted(mut values: Vec<f64>, weight: f64) -> Vec<f64> {
    values.iter_mut().for_each(|v| *v *= weight);
    values
}

/// The reason: each joint's law, its friction velocity against its RMS speed, and how much
/// better it fits than `sign(q̇)`.
fn explain(
    laws: &CoulombLaws,
    scores: &[(usize, Vec<(CoulombShape, f64)>)],
    rms_speed: &[f64],
    folds: usize,
    unresolved: Vec<UnresolvedLaw>,
) -> Choice {
    let joints = scores
        .iter()
        .map(|(k, errors)| {
            let law = laws.shape(*k);
            let error = errors.iter().find(|(l, _)| *l == law).map_or(1.0, |(_, e)| *e);
            let velocity = law.epsilon();
            JointLaw {
                joint: *k,
                velocity,
                per_rms_speed: velocity.map_or(0.0, |v| v / rms_speed[*k]),
                error_share: error,
            }
        })
        .collect();
    Choice::LawsChosen {
        joints,
        shares: [FRICTION_VELOCITY_SHARES[0], FRICTION_VELOCITY_SHARES[FRICTION_VELOCITY_SHARES.len() - 1]],
        folds,
        standard_errors: LAW_STANDARD_ERRORS,
        t: standard_errors(folds),
        unresolved,
    }
}

/// `XᵀX` and `Xᵀy` of the problem's columns and `yᵀy` over a stretch of its samples.
#[derive(Clone)]
struct Gram {
    g: Mat<f64>,
    b: Vec<f64>,
    yy: f64,
}

impl Gram {
    fn over(problem: &LawProblem, samples: &Range<usize>) -> Self {
        let p = problem.columns.len();
        let rows = samples.start * problem.dof..samples.end * problem.dof;
        let mut gram =
            Self { g: Mat::zeros(p, p), b: vec![0.0; p], yy: dot(&problem.y[rows.clone()], &problem.y[rows]) };
        for c in 0..p {
            gram.replace(problem, samples, c);
        }
        gram
    }

    /// Column `c` changed: its row and column of `XᵀX`, and its entry of `Xᵀy`.
    fn replace(&mut self, problem: &LawProblem, samples: &Range<usize>, c: usize) {
        let rows = samples.start * problem.dof..samples.end * problem.dof;
        let changed = &problem.columns[c][rows.clone()];
        for i in 0..problem.columns.len() {
            let v = dot(&problem.columns[i][rows.clone()], changed);
            self.g[(i, c)] = v;
            self.g[(c, i)] = v;
        }
        self.b[c] = dot(changed, &problem.y[rows]);
    }

    /// The sums over the union of the disjoint stretches `parts` summed over.
    fn sum<'a>(mut parts: impl Iterator<Item = &'a Gram>) -> Self {
        let mut total = parts.next().expect("a fold has stretches").clone();
        for part in parts {
            total.g += &part.g;
            total.b.iter_mut().zip(&part.b).for_each(|(t, b)| *t += b);
            total.yy += part.yy;
        }
        total
    }
}

/// A candidate column's products with the problem over a stretch of samples: with every column
/// (`xv`), with itself and with the target.
#[derive(Clone)]
struct Products {
    xv: Vec<f64>,
    vv: f64,
    vy: f64,
}

/// A candidate column that lives on one joint's rows: one value per sample.
#[derive(Clone, Copy)]
struct JointColumn<'a> {
    joint: usize,
    values: &'a [f64],
}

impl Products {
    fn over(problem: &LawProblem, candidate: JointColumn, samples: &Range<usize>) -> Self {
        let (dof, k) = (problem.dof, candidate.joint);
        let values = &candidate.values[samples.clone()];
        let on_joint = |x: &[f64]| strided_dot(values, &x[samples.start * dof..], dof, k);
        let xv = problem.columns.iter().map(|c| on_joint(c)).collect();
        Self { xv, vv: dot(values, values), vy: on_joint(&problem.y) }
    }

    /// The products over the union of the disjoint stretches `parts` were taken over.
    fn sum<'a>(parts: impl IntoIterator<Item = &'a Products>) -> Self {
        let mut parts = parts.into_iter();
        let mut total = parts.next().expect("a fold has stretches").clone();
        for part in parts {
            total.xv.iter_mut().zip(&part.xv).for_each(|(t, x)| *t += x);
            total.vv += part.vv;
            total.vy += part.vy;
        }
        total
    }
}

/// `Σ_s v_s x_{s·dof + k}`: a joint's column against one joint's rows of a row-major `N × dof`
/// column, in four interleaved partial sums as [`dot`] (a single running sum waits on each add).
fn strided_dot(values: &[f64], x: &[f64], dof: usize, k: usize) -> f64 {
    let mut sums = [0.0; 4];
    let chunks = values.chunks_exact(4);
    let done = values.len() - chunks.remainder().len();
    for (i, v) in chunks.enumerate() {
        let at = 4 * i * dof + k;
        for l in 0..4 {
            sums[l] += v[l] * x[at + l * dof];
        }
    }
    let tail: f64 = (done..values.len()).map(|s| values[s] * x[s * dof + k]).sum();
    (sums[0] + sums[1]) + (sums[2] + sums[3]) + tail
}

/// A fold spans at least this many guards, so that half of it is scored clear of the samples its
/// fit saw.
const GUARDS_PER_FOLD: usize = 4;

/// Fewer folds than this and the data do not choose a law: two paired differences are no spread
/// to call a standard error. Few folds leave each fit extrapolating over a large share of the
/// log, and the spread of a few differences is itself uncertain, which `standard_errors` answers
/// with Student's t: with 3 folds and one plain standard error, a 6 s period (the generator's KUKA,
/// sign law, filtered at 1.7 Hz) chose laws at 0.75 and 0.81 × the RMS speed and fitted at 93 %
/// mean FP% against 99.5 with sign(q̇); with the t margin it keeps sign(q̇). Five folds, the usual
/// minimum, would leave the smooth-law closed loop's 15 s period at 0.67 Hz (3 folds) without its
/// law (docs/identification.md §7).
pub const LAW_MIN_FOLDS: usize = 3;

/// As many folds as fit, at most [`LAW_FOLDS`], each [`GUARDS_PER_FOLD`] guards long. Folds any
/// shorter would score samples within the filter's memory of the ones fitted, which share their
/// noise: the score would then reward a law for fitting that noise, and a wide law that trades
/// against viscous friction wins on `sign(q̇)` data (a 6 s period filtered at 1.7 Hz, whose
/// memory of 0.47 s is longer than a tenth of it).
fn fold_count(samples: usize, guard: usize) -> usize {
    (samples / (GUARDS_PER_FOLD * guard.max(1))).min(LAW_FOLDS)
}

/// The cross-validation's folds: [`LAW_FOLDS`] contiguous stretches of the samples, each with its
/// scored interior (the guard left off both ends). The sums are taken once over each fold's three
/// disjoint stretches (the guard before its interior, the interior, the guard after) and added up
/// for the fold and the whole: a third of the passes over the log that summing the whole, each
/// fold and each interior apart would take.
struct Folds {
    /// Each fold's guard before, interior and guard after, with their Gram matrices.
    parts: Vec<[(Range<usize>, Gram); 3]>,
    /// The Gram matrices of each fold and of the whole, the sums of `parts`'.
    folds: Vec<Gram>,
    whole: Gram,
}

impl Folds {
    /// `count` folds of the problem's samples ([`fold_count`]).
    fn of(problem: &LawProblem, count: usize) -> Self {
        let samples = problem.y.len() / problem.dof.max(1);
        let count = count.max(1);
        let bounds: Vec<usize> = (0..=count).map(|f| f * samples / count).collect();
        let parts: Vec<[(Range<usize>, Gram); 3]> = bounds
            .windows(2)
            .map(|w| {
                let guard = problem.guard.min((w[1] - w[0]) / GUARDS_PER_FOLD);
                let (inner_start, inner_end) = (w[0] + guard, w[1] - guard);
                [w[0]..inner_start, inner_start..inner_end, inner_end..w[1]].map(|r| {
                    let gram = Gram::over(problem, &r);
                    (r, gram)
                })
            })
            .collect();
        let (folds, whole) = Self::totals(&parts);
        Self { parts, folds, whole }
    }

    fn totals(parts: &[[(Range<usize>, Gram); 3]]) -> (Vec<Gram>, Gram) {
        let folds: Vec<Gram> = parts.iter().map(|p| Gram::sum(p.iter().map(|(_, g)| g))).collect();
        let whole = Gram::sum(folds.iter());
        (folds, whole)
    }

    fn replace(&mut self, problem: &LawProblem, c: usize) {
        self.parts.iter_mut().flatten().for_each(|(r, gram)| gram.replace(problem, r, c));
        (self.folds, self.whole) = Self::totals(&self.parts);
    }

    /// Each fold's weighted squared error on its interior, predicted by the fit on the other folds
    /// of every column but `c` and joint `k`'s candidate column `values`; `None` where a fit's
    /// columns are dependent.
    fn heldout_errors(&self, problem: &LawProblem, c: usize, candidate: JointColumn) -> Option<Vec<f64>> {
        let whole = &self.whole;
        let kept: Vec<usize> = (0..whole.g.nrows()).filter(|&i| i != c && whole.g[(i, i)] > 0.0).collect();
        let parts: Vec<[Products; 3]> =
            self.parts.iter().map(|p| p.each_ref().map(|(r, _)| Products::over(problem, candidate, r))).collect();
        let folds: Vec<Products> = parts.iter().map(Products::sum).collect();
        let all = Products::sum(&folds);
        self.parts
            .iter()
            .zip(&self.folds)
            .zip(parts.iter().zip(&folds))
            .map(|((fold_parts, fold_gram), (products, left_out))| {
                let (interior_gram, scored) = (&fold_parts[1].1, &products[1]);
                // The fit on the other folds: the whole less this one.
                let (matrix, rhs) = system(
                    &kept,
                    Sums { gram: whole, products: &all },
                    Some(Sums { gram: fold_gram, products: left_out }),
                );
                let theta = dense::solve_gram(matrix.as_ref(), &rhs, Unseen::Refused)?;
                let (h, r) = system(&kept, Sums { gram: interior_gram, products: scored }, None);
                let fitted = dense::times(h.as_ref(), &theta);
                Some((interior_gram.yy - 2.0 * dot(&theta, &r) + dot(&theta, &fitted)).max(0.0))
            })
            .collect()
    }
}

/// The sums of a stretch of samples: the problem's [`Gram`] and a candidate's [`Products`].
#[derive(Clone, Copy)]
struct Sums<'a> {
    gram: &'a Gram,
    products: &'a Products,
}

/// The normal equations over the `kept` columns and the candidate (last): of `sums`, less
/// `minus` where given.
fn system(kept: &[usize], sums: Sums, minus: Option<Sums>) -> (Mat<f64>, Vec<f64>) {
    let p = kept.len();
    let less = |f: &dyn Fn(&Gram, &Products) -> f64| {
        f(sums.gram, sums.products) - minus.map_or(0.0, |m| f(m.gram, m.products))
    };
    let mut matrix = Mat::zeros(p + 1, p + 1);
    let mut rhs = vec![0.0; p + 1];
    for (i, &a) in kept.iter().enumerate() {
        for (j, &b) in kept.iter().enumerate() {
            matrix[(i, j)] = less(&|g, _| g.g[(a, b)]);
        }
        let cross = less(&|_, x| x.xv[a]);
        matrix[(i, p)] = cross;
        matrix[(p, i)] = cross;
        rhs[i] = less(&|g, _| g.b[a]);
    }
    matrix[(p, p)] = less(&|_, x| x.vv);
    rhs[p] = less(&|_, x| x.vy);
    (matrix, rhs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::convert::Infallible;

    /// One joint moving as a sine, its torque a viscous term plus dry friction rising as
    /// tanh(q̇/v_true) plus a little noise: the friction velocity is found to within a few per cent
    /// on the grid and between its points, and a torque with sign(q̇) friction keeps sign(q̇).
    #[test]
    fn the_friction_velocity_of_a_smooth_law_is_found_and_a_sharp_law_stays_sign() {
        let n = 4000;
        let velocity: Vec<f64> =
            (0..n).map(|i| 0.3 * (i as f64 * 0.01).sin() + 0.05 * (i as f64 * 0.037).cos()).collect();
        let rms = (velocity.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        let noise = |i: usize| 1e-3 * ((i * 7919 % 101) as f64 / 50.0 - 1.0);
        for truth in
            [CoulombShape::Tanh { epsilon: 0.05 * rms }, CoulombShape::Tanh { epsilon: 0.07 * rms }, CoulombShape::Sign]
        {
            let y: Vec<f64> =
                velocity.iter().enumerate().map(|(i, v)| 2.0 * v + 0.7 * truth.eval(*v) + noise(i)).collect();
            let column = |law: CoulombShape| velocity.iter().map(|v| law.eval(*v)).collect::<Vec<f64>>();
            let columns =
                |_: usize, laws: &[CoulombShape]| Ok::<_, Infallible>(laws.iter().map(|l| column(*l)).collect());
            let problem = LawProblem {
                columns: vec![velocity.clone(), column(CoulombShape::Sign)],
                y,
                dof: 1,
                coulomb: vec![(0, 1)],
                weights: vec![1.0],
                guard: 20,
            };
            let chosen =
                choose_laws(problem, &[rms], &CoulombLaws::undeclared(1), columns, |_, _| Resolution::EXACT).unwrap();
            match (truth.epsilon(), chosen.laws.shape(0).epsilon()) {
                (Some(v), Some(found)) => {
                    assert!((found / v - 1.0).abs() < 0.03, "{found} against {v}: {}", chosen.reason)
                }
                (None, None) => {}
                _ => panic!("{truth} chosen as {}: {}", chosen.laws.shape(0), chosen.reason),
            }
            assert!(chosen.laws.is_declared());
        }
    }

    /// The laws one joint chooses, judged by `resolves`, on a sine whose torque is viscous plus
    /// tanh(q̇/v) friction; and that v.
    fn chosen_on_a_sine(resolves: impl Fn(usize, f64) -> Resolution) -> (ChosenLaws, f64) {
        let n = 4000;
        let velocity: Vec<f64> = (0..n).map(|i| 0.3 * (i as f64 * 0.01).sin()).collect();
        let rms = (velocity.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        let truth = CoulombShape::Tanh { epsilon: 0.05 * rms };
        let y: Vec<f64> = velocity.iter().map(|v| 2.0 * v + 0.7 * truth.eval(*v)).collect();
        let column = |law: CoulombShape| velocity.iter().map(|v| law.eval(*v)).collect::<Vec<f64>>();
        let columns = |_: usize, laws: &[CoulombShape]| Ok::<_, Infallible>(laws.iter().map(|l| column(*l)).collect());
        let problem = LawProblem {
            columns: vec![velocity.clone(), column(CoulombShape::Sign)],
            y,
            dof: 1,
            coulomb: vec![(0, 1)],
            weights: vec![1.0],
            guard: 20,
        };
        let chosen = choose_laws(problem, &[rms], &CoulombLaws::undeclared(1), columns, resolves).unwrap();
        (chosen, truth.epsilon().unwrap())
    }

    /// The joints a choice refused a law on, each with what `of` reads of its reason.
    fn refused(chosen: &ChosenLaws, of: impl Fn(&UnresolvedLaw) -> usize) -> Vec<(usize, usize)> {
        match &chosen.reason {
            Choice::LawsChosen { unresolved, .. } => unresolved.iter().map(|u| (u.joint, of(u))).collect(),
            _ => Vec::new(),
        }
    }

    /// The smooth law the data fit is kept only where the velocity it switches with strays from
    /// the motion's by less than its friction velocity: a stray of twice v keeps sign(q̇) and
    /// names the stray, one of half v keeps the law.
    #[test]
    fn a_law_narrower_than_its_velocitys_stray_keeps_sign_and_says_so() {
        let stray =
            |share: f64| move |_: usize, v: f64| Resolution { stray: share * v, samples: 50, transition: 0, needed: 0 };
        let (sign, _) = chosen_on_a_sine(stray(2.0));
        assert_eq!(sign.laws.shape(0), CoulombShape::Sign, "{}", sign.reason);
        assert_eq!(refused(&sign, |u| u.samples), [(0, 50)], "{}", sign.reason);
        let (kept, truth) = chosen_on_a_sine(stray(0.5));
        let found = kept.laws.shape(0).epsilon().expect("the smooth law is kept");
        assert!((found / truth - 1.0).abs() < 0.03, "{}", kept.reason);
        assert!(refused(&kept, |u| u.samples).is_empty(), "{}", kept.reason);
    }

    /// A smooth law the data fit is kept only where enough samples in its transition are clear of
    /// rests and stops: with fewer than needed, sign(q̇) stays and the choice says how many there
    /// were; with as many as needed, the law is kept.
    #[test]
    fn a_law_whose_transition_lies_beside_stops_keeps_sign_and_says_so() {
        let clear = |transition: usize| {
            move |_: usize, _: f64| Resolution { transition, samples: 100, needed: 60, ..Resolution::EXACT }
        };
        let (sign, _) = chosen_on_a_sine(clear(59));
        assert_eq!(sign.laws.shape(0), CoulombShape::Sign, "{}", sign.reason);
        assert_eq!(refused(&sign, |u| u.transition), [(0, 59)], "{}", sign.reason);
        assert!(sign.reason.to_string().contains("only 59 of the 100 samples"), "{}", sign.reason);
        let (kept, truth) = chosen_on_a_sine(clear(60));
        let found = kept.laws.shape(0).epsilon().expect("the smooth law is kept");
        assert!((found / truth - 1.0).abs() < 0.03, "{}", kept.reason);
        assert!(refused(&kept, |u| u.transition).is_empty(), "{}", kept.reason);
    }

    /// A log too short, for its filter's memory, to hold [`LAW_MIN_FOLDS`] stretches that share no
    /// filtered noise keeps its declared law and says why, even where a smooth law would fit.
    #[test]
    fn a_log_too_short_for_its_filter_keeps_its_law_and_says_so() {
        let n = 400;
        let velocity: Vec<f64> = (0..n).map(|i| 0.3 * (i as f64 * 0.05).sin()).collect();
        let smooth = CoulombShape::Tanh { epsilon: 0.03 };
        let y: Vec<f64> = velocity.iter().map(|v| 2.0 * v + 0.7 * smooth.eval(*v)).collect();
        let column = |law: CoulombShape| velocity.iter().map(|v| law.eval(*v)).collect::<Vec<f64>>();
        let columns = |_: usize, laws: &[CoulombShape]| Ok::<_, Infallible>(laws.iter().map(|l| column(*l)).collect());
        let problem = |guard| LawProblem {
            columns: vec![velocity.clone(), column(CoulombShape::Sign)],
            y: y.clone(),
            dof: 1,
            coulomb: vec![(0, 1)],
            weights: vec![1.0],
            guard,
        };
        let rms = (velocity.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        let short = choose_laws(
            problem(n / (GUARDS_PER_FOLD * LAW_MIN_FOLDS) + 1),
            &[rms],
            &CoulombLaws::undeclared(1),
            columns,
            |_, _| Resolution::EXACT,
        )
        .unwrap();
        assert_eq!(short.laws.shape(0), CoulombShape::Sign, "{}", short.reason);
        let too_few =
            matches!(short.reason, Choice::LawsKept { folds, min_folds: LAW_MIN_FOLDS, .. } if folds < LAW_MIN_FOLDS);
        assert!(too_few, "{}", short.reason);
        let long_enough =
            choose_laws(problem(5), &[rms], &CoulombLaws::undeclared(1), columns, |_, _| Resolution::EXACT).unwrap();
        assert!(long_enough.laws.shape(0).epsilon().is_some(), "{}", long_enough.reason);
    }

    /// The margin from few folds is Student's t at the normal's one-σ level: scipy's
    /// `t.ppf(norm.cdf(1), folds − 1)`.
    #[test]
    fn the_margin_widens_for_few_folds_as_students_t_does() {
        for (folds, scipy) in [(3, 1.3212773729262555), (5, 1.141626629090954), (10, 1.0587276657414018)] {
            assert!((standard_errors(folds) - scipy).abs() < 1e-6, "{folds}: {}", standard_errors(folds));
        }
    }

    /// The held-out error the Gram updates give a candidate is that of fitting the columns
    /// directly on the other folds and predicting the fold's interior.
    #[test]
    fn the_heldout_error_of_a_candidate_is_the_direct_fit_on_the_other_folds() {
        let n = 300;
        let a: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.1).sin()).collect();
        let b: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.023).cos()).collect();
        let y: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.05).sin() + 0.1 * (i % 7) as f64).collect();
        let candidate: Vec<f64> = (0..n).map(|s| ((s as f64) * 0.031).tanh()).collect();
        // Column 1 is the one the candidate replaces.
        let problem = LawProblem {
            columns: vec![a.clone(), b.clone()],
            y: y.clone(),
            dof: 2,
            coulomb: vec![(1, 1)],
            weights: vec![1.0; 2],
            guard: 5,
        };
        let got = Folds::of(&problem, LAW_FOLDS)
            .heldout_errors(&problem, 1, JointColumn { joint: 1, values: &candidate })
            .unwrap();
        assert_eq!(got.len(), LAW_FOLDS);
        let mut c = vec![0.0; 2 * n];
        for s in 0..n {
            c[2 * s + 1] = candidate[s];
        }
        let fold = n / LAW_FOLDS;
        for (f, got) in got.iter().enumerate() {
            let (start, end) = (f * fold, (f + 1) * fold);
            let train: Vec<usize> = (0..2 * n).filter(|r| !(2 * start..2 * end).contains(r)).collect();
            let x = Mat::from_fn(train.len(), 2, |r, j| [&a, &c][j][train[r]]);
            let target = Mat::from_fn(train.len(), 1, |r, _| y[train[r]]);
            let beta = dense::inverse((x.transpose() * &x).as_ref()).unwrap() * (x.transpose() * target);
            let beta = [beta[(0, 0)], beta[(1, 0)]];
            let expected: f64 =
                (2 * (start + 5)..2 * (end - 5)).map(|r| (y[r] - a[r] * beta[0] - c[r] * beta[1]).powi(2)).sum();
            assert!((got / expected - 1.0).abs() < 1e-9, "fold {f}: {got} against {expected}");
        }
    }
}
