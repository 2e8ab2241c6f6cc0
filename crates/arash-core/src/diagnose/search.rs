//! The search: set up the weighted problem, align the log, then add the most useful effect per
//! round until nothing passes (the module documentation of [`super`] lists the rule).

use std::borrow::Cow;

use super::band_choice::{choose_band, BandChoice};
use super::calibration_error;
use super::candidates::{candidates, not_the_cable};
use super::delay::search_delay;
use super::findings::{
    rejection, DiagnoseSettings, Diagnosis, ErrorSummary, Finding, Rejection, RejectionReason, Reversion,
    ScaleRefinement, Series, StartedFrom, TooHeavy,
};
use super::gain_share::GainErrors;
use super::guard;
use super::inputs::Context;
use super::options::{DiagnoseError, DiagnoseOptions, PAYLOAD_MASS_SIGMAS};
use super::outcome::{declared_model, series, Source};
use super::regression::{
    self, least_squares, residual, test_group, Column, Fitted, GroupTest, NormalEquations, Rows, Untested,
};
use super::weighted_fit::{error_summary, model_columns, Candidate, HeldOut, HeldOutBase, Problem};
use super::Runs;
use crate::effects::{EffectKind, EffectTerm};
use crate::model::{CoulombLaws, JointKind, Model};
use crate::model_file::{ModelFile, Settings};
use crate::signal::log::{Declared, Log};

/// Whose Coulomb laws the diagnosis fits with, against a given model.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Laws {
    /// The given model's: its Coulomb coefficients belong to them.
    OfGiven,
    /// Its own, as without a model (refitting only): the given model is the start to compare
    /// with, predicting with its own.
    Own,
}

/// Diagnose `train` against the declared dynamics (refitted, or `given`), holding out
/// `validation` when it is given.
pub(super) fn diagnose_against(
    declared: Declared,
    (train, validation): (Log, Option<Runs>),
    given: Option<&ModelFile>,
    laws: Laws,
    options: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    let choice = band_for(declared, (train, validation.as_ref()), given, laws, options)?;
    diagnose_in_band(declared, (train, validation), given, laws, options, &choice)
}

/// A given model's Coulomb coefficients belong to the laws it was fitted with; without one
/// the robot's declared laws are used, or, where it declares none, each joint's is chosen
/// from the data with the band (docs/diagnosis.md, "The Coulomb law").
fn start_model<'a>(model: &'a Model, given: Option<&ModelFile>, laws: Laws) -> Cow<'a, Model> {
    match (given, laws) {
        (Some(file), Laws::OfGiven) => file.with_its_law(model),
        _ => Cow::Borrowed(model),
    }
}

/// The band [`diagnose_against`] chooses, and with it each joint's Coulomb law where the
/// diagnosis chooses them. It depends on the laws, not on what is refitted, so that a diagnosis
/// run again with other parameters held can share it.
pub(super) fn band_for(
    declared: Declared,
    (train, validation): (Log, Option<&Runs>),
    given: Option<&ModelFile>,
    laws: Laws,
    options: &DiagnoseOptions,
) -> Result<BandChoice, DiagnoseError> {
    options.validate(declared.model.dof())?;
    validation.map(Runs::check).transpose()?;
    let model = start_model(declared.model, given, laws);
    let refit = given.is_none() || options.refit;
    let choose_laws = (refit || laws == Laws::Own) && !model.coulomb_laws.is_declared();
    choose_band(&model, declared.base, train, validation, options, choose_laws)
}

/// [`diagnose_against`] in the band `choice` ([`band_for`]'s, with the same laws).
pub(super) fn diagnose_in_band(
    declared: Declared,
    (train, validation): (Log, Option<Runs>),
    given: Option<&ModelFile>,
    laws: Laws,
    options: &DiagnoseOptions,
    choice: &BandChoice,
) -> Result<Diagnosis, DiagnoseError> {
    let mut model = start_model(declared.model, given, laws);
    if let Some(chosen) = &choice.laws {
        model.to_mut().coulomb_laws = chosen.laws.clone();
    }
    let mut ctx = Context::new(&model, declared.base, train, validation, given, options, choice)?;
    // 1. Delay.
    let (delay, delay_outcome) = if options.effects.contains(&EffectKind::Delay) && ctx.max_shift() > 0 {
        let (delay, outcome) = search_delay(&ctx);
        (delay, Some(outcome))
    } else {
        (0, None)
    };
    let mut state = State::default();
    let mut skipped = Vec::new();
    match delay_outcome {
        Some(Ok(finding)) => state.accepted.push(finding),
        Some(Err(rejection)) => skipped.push(rejection),
        None => {}
    }
    // 2. Forward selection.
    let problem = ctx.problem(&ctx.train, delay);
    let heldout = ctx.heldout(delay);
    let (templates, not_searched) = candidates(&model, &ctx.train, options, choice.laws.is_some());
    skipped.extend(not_searched);
    let pool = ctx.pool(templates, &problem, &heldout);
    let gain_errors = GainErrors::of(&ctx, &problem);
    let source = Source::of(&train, ctx.given.and_then(|g| g.data.fingerprint.as_deref()));
    let (calibration, reason) = calibration_error::directions(&ctx, &problem, gain_errors.as_ref(), &source);
    ctx.train.pre.choices.reasons.extend(reason);
    let mut search = Search { ctx: &ctx, problem: &problem, heldout: &heldout, pool, gain_errors, calibration };
    search.select(&mut state)?;
    // 3. Final joint fit, errors before and after, and the updated model.
    search.finish(state, delay, skipped, declared.urdf, &source)
}

/// Where the search stands: what it accepted, in order, and why each other candidate is out for
/// now (a rejection without a p-value is final).
#[derive(Default)]
struct State {
    accepted: Vec<Finding>,
    chosen: Vec<usize>,
    status: Vec<Option<Rejection>>,
    too_heavy: Option<TooHeavy>,
}

/// A candidate that passed every check of a round.
struct Passed {
    /// Index into the round's tests.
    test: usize,
    /// Held-out gain on the joint it helps most, per joint, and over the whole robot.
    gain: f64,
    gains: Vec<f64>,
    total: f64,
    /// The Holm threshold its p-value passed.
    threshold: f64,
}

/// An accepted term with its scale refined (`Search::refine_scale`): its columns, its test and
/// held-out gains at the refined scale.
struct Refined {
    candidate: Candidate,
    refinement: ScaleRefinement,
    test: GroupTest,
    gain: f64,
    gains: Vec<f64>,
}

/// A payload with its inertia (`Search::with_inertia`): its columns, its test against the round's
/// model and its held-out gains.
struct Upgraded {
    candidate: Candidate,
    test: GroupTest,
    gain: f64,
    gains: Vec<f64>,
}

/// Steps of a scale's refinement: each keeps 0.55 of the bracket ([`DICHOTOMY_GAP`]), so a
/// bracket of a factor of 4 (a grid a factor of 2 apart) ends within 1 % of the scale after 7.
const REFINE_STEPS: usize = 7;

/// Half the distance between a dichotomy's two trials, as a share of the bracket.
const DICHOTOMY_GAP: f64 = 0.05;

/// A refined scale closer to the grid's than this (relative) is the grid's.
const REFINE_TOLERANCE: f64 = 1e-3;

/// The maximiser of a unimodal `f` on `[a, b]` by dichotomy: each step tries `f` either side of
/// the bracket's middle, the two on both cores, and keeps the side of the larger.
fn dichotomy_max(mut a: f64, mut b: f64, steps: usize, f: impl Fn(f64) -> f64 + Sync) -> f64 {
    for _ in 0..steps {
        let (middle, gap) = (0.5 * (a + b), DICHOTOMY_GAP * (b - a));
        let values = crate::parallel::map(vec![middle - gap, middle + gap], &f);
        if values[0] >= values[1] {
            b = middle + gap;
        } else {
            a = middle - gap;
        }
    }
    0.5 * (a + b)
}

/// The forward selection over one prepared problem.
struct Search<'a> {
    ctx: &'a Context<'a>,
    problem: &'a Problem,
    heldout: &'a HeldOut,
    /// Every candidate; an accepted one's scale is refined in place.
    pool: Vec<Candidate>,
    /// The calibrated drive gains' errors, when the torque came from currents through them.
    gain_errors: Option<GainErrors>,
    /// The given model's calibration error on the problem's rows, which every test counts.
    calibration: Vec<Vec<f64>>,
}

impl Search<'_> {
    fn select(&mut self, state: &mut State) -> Result<(), DiagnoseError> {
        state.status = vec![None; self.pool.len()];
        for round in 1.. {
            if state.accepted.len() >= self.ctx.options.max_effects || !self.round(round, state)? {
                break;
            }
        }
        Ok(())
    }

    /// One round: test every open candidate against the current model, judge the significant
    /// ones, and add the most useful. `false` when nothing was added.
    fn round(&mut self, round: usize, state: &mut State) -> Result<bool, DiagnoseError> {
        let dof = self.problem.dof;
        let base = NormalEquations::over(
            model_columns(self.problem, &self.pool, &state.chosen),
            &self.problem.y,
            dof,
            Rows::All,
        );
        let coef = base.solve().ok_or(DiagnoseError::Singular)?;
        let e0 = residual(&base.columns, &coef, &self.problem.y, dof);
        let tested = self.test_open(&base, &e0, state);
        if tested.is_empty() {
            return Ok(false);
        }
        let (mut passing, lighter, scoring) = self.judge(round, &tested, &base, &coef, state);
        // A mass taken off one body can look like a mass put on another (a parallelogram's links
        // pull against each other): the positive explanation stands unless the missing mass
        // explains clearly more, by the margin `most_useful` gives a simpler term.
        if let Some((total, heavy)) = lighter {
            if passing.iter().all(|p| p.total < COMPARABLE_GAIN * total) {
                state.too_heavy = Some(heavy);
                return Ok(false);
            }
        }
        // The most useful candidate that leaves every effect its physical sign in the joint fit.
        let best = loop {
            let Some(best) = most_useful(&passing, |o| self.pool[tested[o].0].columns.len()) else {
                return Ok(false);
            };
            let (i, t) = &tested[passing[best].test];
            match self.flipped_by(*i, state, &base) {
                None => break passing.swap_remove(best),
                Some((label, coefficient)) => {
                    let reason = RejectionReason::FlipsSign { p_value: t.p_value, label, coefficient };
                    let gain = Some(passing[best].gain);
                    state.status[*i] =
                        Some(rejection(self.ctx.model, &self.pool[*i].term, reason, Some(t.p_value), gain));
                    passing.swap_remove(best);
                }
            }
        };
        let (winner, mut test) = tested[best.test].clone();
        let aliases = self.aliases(winner, &tested, &e0, state);
        let (mut gain, mut gains) = (best.gain, best.gains);
        // At most one applies: a payload has no scale to refine, and only a payload an inertia.
        let refined = self.refine_scale(winner, (&base, &e0), state, best.total, scoring.as_ref());
        let upgraded = self.with_inertia(winner, (&base, &e0), state, best.total, scoring.as_ref());
        let refined = match refined {
            Some(r) => {
                self.pool[winner] = r.candidate;
                (test, gain, gains) = (r.test, r.gain, r.gains);
                Some(r.refinement)
            }
            None => None,
        };
        if let Some(upgrade) = upgraded {
            self.pool[winner] = upgrade.candidate;
            (test, gain, gains) = (upgrade.test, upgrade.gain, upgrade.gains);
        }
        state.chosen.push(winner);
        let mut term = self.pool[winner].term.clone();
        term.coefficients = test.coefficients.clone();
        term.sigma = test.sigma.clone();
        let model = self.ctx.model;
        state.accepted.push(Finding {
            name: term.kind.id().into(),
            joints: term.joints(dof),
            label: term.describe(&model.joint_names()),
            term,
            statistic: test.f_statistic,
            batches: test.batches,
            batch_s: test.batch_samples as f64 / self.ctx.train.kept_rate(),
            p_value: test.p_value,
            threshold: best.threshold,
            heldout_gain: gain,
            heldout_gain_per_joint: gains,
            aliases,
            mass_kg: None,
            mass_sigma_kg: None,
            body: None,
            centre_of_mass_m: None,
            sigma_from_gains: vec![],
            round,
            refined,
        });
        state.accepted.last_mut().expect("just pushed").weigh();
        Ok(true)
    }

    /// The block Wald test of every open candidate; those the model already explains are set
    /// aside as not identifiable.
    fn test_open(&self, base: &NormalEquations, e0: &[f64], state: &mut State) -> Vec<(usize, GroupTest)> {
        let ctx = self.ctx;
        let open: Vec<usize> = (0..self.pool.len())
            .filter(|i| !state.chosen.contains(i) && state.status[*i].as_ref().is_none_or(|r| r.p_value.is_some()))
            .collect();
        let tests = crate::parallel::map(open, |i| {
            let group: Vec<&Column> = self.pool[i].columns.iter().collect();
            (i, test_group(base, e0, &group, ctx.batching, &self.calibration))
        });
        let mut tested = Vec::new();
        let max_vif = ctx.options.max_vif;
        for (i, outcome) in tests {
            let reason = match outcome {
                Ok(t) if t.unexplained * max_vif >= 1.0 => {
                    tested.push((i, t));
                    continue;
                }
                Ok(GroupTest { unexplained, .. }) | Err(Untested::Dependent { unexplained }) => {
                    RejectionReason::NotIdentifiable { vif: 1.0 / unexplained, max_vif }
                }
                Err(Untested::TooFewBatches { batches, columns }) => RejectionReason::TooShort { batches, columns },
            };
            state.status[i] = Some(rejection(ctx.model, &self.pool[i].term, reason, None, None));
        }
        tested
    }

    /// Holm's procedure over the round's tests, then the physical checks and the held-out gain;
    /// what fails is marked with its reason, what passes is returned, with the most useful
    /// payload of negative mass that would have passed but for its sign (and its whole-robot gain).
    fn judge(
        &self,
        round: usize,
        tested: &[(usize, GroupTest)],
        base: &NormalEquations,
        coef: &[f64],
        state: &mut State,
    ) -> (Vec<Passed>, Option<(f64, TooHeavy)>, Option<HeldOutBase<'_>>) {
        let base_cols = &base.columns;
        let (ctx, dof) = (self.ctx, self.problem.dof);
        let alpha = ctx.options.alpha;
        let p_values: Vec<f64> = tested.iter().map(|(_, t)| t.p_value).collect();
        let pass = regression::holm(&p_values, alpha);
        let mut order: Vec<usize> = (0..tested.len()).collect();
        order.sort_by(|&a, &b| p_values[a].total_cmp(&p_values[b]));
        let mut passing = Vec::new();
        let mut lighter: Option<(f64, TooHeavy)> = None;
        let mut scoring: Option<HeldOutBase> = None;
        for (rank, &o) in order.iter().enumerate() {
            let (i, t) = &tested[o];
            let term = &self.pool[*i].term;
            let threshold = regression::holm_threshold(alpha, tested.len(), rank);
            let p_value = t.p_value;
            let verdict = (|| {
                if !pass[o] {
                    return Err((RejectionReason::NotSignificant { p_value, threshold, round }, None));
                }
                if let Some(reason) = not_a_mass(term, t, ctx.model) {
                    return Err((reason, None));
                }
                if let Some(reason) = below_floor(term, t) {
                    return Err((reason, None));
                }
                // A payload of negative mass is judged on (below): it may say the model is too heavy.
                let flipped = wrong_sign(term, t);
                if let Some(coefficient) = flipped.filter(|_| term.kind != EffectKind::Payload) {
                    return Err((RejectionReason::WrongSign { p_value, coefficient }, None));
                }
                if let Some(reason) = not_the_cable(ctx.model, ctx.base, &ctx.free, coef, ctx.given, term, t) {
                    return Err((reason, None));
                }
                let scoring = scoring
                    .get_or_insert_with(|| HeldOutBase::new(self.problem, self.heldout, &self.pool, &state.chosen));
                let (gains, total) = scoring.gain(&ctx.floor, *i);
                // Accepted on the joint it helps most, ranked by what it does for the whole
                // robot, so that an effect acting on several joints competes fairly with
                // one-joint terms.
                let gain = term.joints(dof).iter().map(|&k| gains[k]).fold(f64::NEG_INFINITY, f64::max);
                if let Some(coefficient) = flipped {
                    // A payload of negative mass: the model is heavier than the data.
                    let from_gains = self.mass_sigma_from_gains(base_cols, *i);
                    let heavy = TooHeavy {
                        body: term.body.clone().unwrap_or_default(),
                        mass_kg: -coefficient,
                        // The test's σ counts the gains' errors (`diagnose/calibration_error.rs`).
                        mass_sigma_kg: t.sigma.first().copied().unwrap_or(f64::NAN),
                        mass_sigma_from_gains_kg: from_gains,
                        p_value,
                        heldout_gain: gain,
                        round,
                    };
                    if gain >= ctx.options.min_gain && lighter.as_ref().is_none_or(|(best, _)| total > *best) {
                        lighter = Some((total, heavy));
                    }
                    return Err((RejectionReason::WrongSign { p_value, coefficient }, Some(gain)));
                }
                if gain < ctx.options.min_gain {
                    let reason = RejectionReason::SmallGain { p_value, gain, min_gain: ctx.options.min_gain };
                    return Err((reason, Some(gain)));
                }
                Ok(Passed { test: o, gain, gains, total, threshold })
            })();
            match verdict {
                Ok(passed) => {
                    state.status[*i] = None;
                    passing.push(passed);
                }
                Err((reason, gain)) => {
                    state.status[*i] = Some(rejection(ctx.model, term, reason, Some(p_value), gain));
                }
            }
        }
        (passing, lighter, scoring)
    }

    /// The winner's scale refined between its neighbours on the grid, where its effect's scale is
    /// continuous: the search by dichotomy over the scale's logarithm for the largest share of
    /// the round's residual the term explains (the coefficients refitted at each scale: variable
    /// projection). A grid a factor of 2 apart leaves a Stribeck velocity up to 41 % off, and a
    /// slow motion inside it reads the whole difference as a force (docs/force.md). Kept where it
    /// explains more of the training residual, keeps its physical sign, and predicts the held-out
    /// runs at least as well as the grid's scale (`grid_total`, the whole robot's held-out gain;
    /// `scoring`, the round's held-out scoring where the judging made one).
    fn refine_scale(
        &self,
        winner: usize,
        (base, e0): (&NormalEquations, &[f64]),
        state: &State,
        grid_total: f64,
        scoring: Option<&HeldOutBase>,
    ) -> Option<Refined> {
        let term = &self.pool[winner].term;
        let grid = term.scale.filter(|s| term.kind.scale_is_continuous() && *s > 0.0)?;
        let siblings = self.pool.iter().map(|c| &c.term).filter(|t| t.kind == term.kind && t.joint == term.joint);
        let scales: Vec<f64> = siblings.filter_map(|t| t.scale).collect();
        let below = scales.iter().copied().filter(|s| *s < grid).reduce(f64::max);
        let above = scales.iter().copied().filter(|s| *s > grid).reduce(f64::min);
        let (lower, upper) = (below.unwrap_or(grid), above.unwrap_or(grid));
        if lower == upper {
            return None;
        }
        let at = |scale: f64| {
            let mut t = term.clone();
            t.scale = Some(scale);
            t
        };
        let explained = |columns: &[Column]| {
            let group: Vec<&Column> = columns.iter().collect();
            regression::explained(base, e0, &group).unwrap_or(f64::NEG_INFINITY)
        };
        // The trials need the training columns alone; the validation log's are made once, for
        // the scale chosen.
        let trial = |x: f64| explained(&self.ctx.training_columns(&at(x.exp()), self.problem));
        let at_grid = explained(&self.pool[winner].columns);
        let scale = dichotomy_max(lower.ln(), upper.ln(), REFINE_STEPS, trial).exp();
        let candidate = self.ctx.candidate(at(scale), self.problem, self.heldout);
        let explains = explained(&candidate.columns);
        if explains <= at_grid || (scale / grid - 1.0).abs() < REFINE_TOLERANCE {
            return None;
        }
        let group: Vec<&Column> = candidate.columns.iter().collect();
        let test = test_group(base, e0, &group, self.ctx.batching, &self.calibration).ok()?;
        if wrong_sign(&candidate.term, &test).is_some() {
            return None;
        }
        let (gains, total) = self.gains_in_round(&candidate, state, scoring);
        if total < grid_total {
            return None;
        }
        let dof = self.problem.dof;
        let gain = candidate.term.joints(dof).iter().map(|&k| gains[k]).fold(f64::NEG_INFINITY, f64::max);
        let residual_ss: f64 = e0.iter().map(|e| e * e).sum();
        let refinement = ScaleRefinement {
            grid,
            bracket: [lower, upper],
            residual_drop: (explains - at_grid) / residual_ss.max(f64::MIN_POSITIVE),
        };
        Some(Refined { candidate, refinement, test, gain, gains })
    }

    /// A payload accepted with its mass and first moments, with its inertia where the data show
    /// it (`effects/payload.rs`): the inertia's six columns tested beside the payload, at the
    /// search's α and counting the calibration's error, and kept where the payload with them
    /// keeps its mass positive and predicts the held-out runs at least as well (`total`, the
    /// whole robot's held-out gain without them).
    fn with_inertia(
        &self,
        winner: usize,
        (base, e0): (&NormalEquations, &[f64]),
        state: &State,
        total: f64,
        scoring: Option<&HeldOutBase>,
    ) -> Option<Upgraded> {
        let (ctx, dof) = (self.ctx, self.problem.dof);
        let term = &self.pool[winner].term;
        if term.kind != EffectKind::Payload || crate::effects::payload_has_inertia(term) {
            return None;
        }
        let candidate = ctx.candidate(crate::effects::payload_with_inertia(term), self.problem, self.heldout);
        let with_mass: Vec<usize> = state.chosen.iter().copied().chain([winner]).collect();
        let beside =
            NormalEquations::over(model_columns(self.problem, &self.pool, &with_mass), &self.problem.y, dof, Rows::All);
        let e1 = residual(&beside.columns, &beside.solve()?, &self.problem.y, dof);
        let inertia: Vec<&Column> = candidate.columns[self.pool[winner].columns.len()..].iter().collect();
        let added = test_group(&beside, &e1, &inertia, ctx.batching, &self.calibration).ok()?;
        if added.p_value > ctx.options.alpha || added.unexplained * ctx.options.max_vif < 1.0 {
            return None;
        }
        let group: Vec<&Column> = candidate.columns.iter().collect();
        let test = test_group(base, e0, &group, ctx.batching, &self.calibration).ok()?;
        if wrong_sign(&candidate.term, &test).is_some() || test.coefficients.first().is_none_or(|m| *m <= 0.0) {
            return None;
        }
        let (gains, with_inertia) = self.gains_in_round(&candidate, state, scoring);
        if with_inertia < total {
            return None;
        }
        let gain = gains.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Some(Upgraded { candidate, test, gain, gains })
    }

    /// The held-out gains of `candidate` in place of the round's winner, per joint and over the
    /// whole robot: on the round's scoring where the judging made one, else on one made for it.
    fn gains_in_round(&self, candidate: &Candidate, state: &State, scoring: Option<&HeldOutBase>) -> (Vec<f64>, f64) {
        match scoring {
            Some(s) => s.gain_of(&self.ctx.floor, candidate),
            None => HeldOutBase::new(self.problem, self.heldout, &self.pool, &state.chosen)
                .gain_of(&self.ctx.floor, candidate),
        }
    }

    /// The σ the calibrated gains give the mass of payload candidate `i` fitted on `base_cols`.
    fn mass_sigma_from_gains(&self, base_cols: &[&Column], i: usize) -> Option<f64> {
        let errors = self.gain_errors.as_ref()?;
        let columns: Vec<&Column> = base_cols.iter().copied().chain(&self.pool[i].columns).collect();
        errors.sigma(&columns, self.problem.dof)?.get(base_cols.len()).copied()
    }

    /// The effect (accepted, or `candidate` itself) whose coefficient the joint fit of the model,
    /// the accepted effects and `candidate` gives the sign its effect cannot have, with that
    /// coefficient. Each effect was tested with the sign right against the model of its round; a
    /// later one that flips it means the two share some other error between them, and neither
    /// can be reported as what it claims. Rotor inertia on every joint is left to its own test,
    /// which allows a nil joint within its σ. `base` is the round's model (its columns, Gram
    /// matrix and `Xᵀy`), to which the candidate's columns are added.
    fn flipped_by(&self, candidate: usize, state: &State, base: &NormalEquations) -> Option<(String, f64)> {
        let (problem, pool) = (self.problem, &self.pool);
        let group: Vec<&Column> = pool[candidate].columns.iter().collect();
        let x = base.with_group(&group, &problem.y)?;
        let chosen = state.chosen.iter().chain([&candidate]);
        let terms = chosen.map(|&i| (&pool[i].term, pool[i].columns.len()));
        let (term, coefficient) = first_flipped(terms, &x, problem.free_columns().count())?;
        Some((term.describe(&self.ctx.model.joint_names()), coefficient))
    }

    /// Candidates that passed too but that the winner explains: its aliases, rejected as such.
    fn aliases(&self, winner: usize, tested: &[(usize, GroupTest)], e0: &[f64], state: &mut State) -> Vec<String> {
        /// The share of a candidate's unexplained part the winner may leave and still alias it.
        const ALIAS_LEFT: f64 = 0.05;
        let (ctx, dof) = (self.ctx, self.problem.dof);
        let names = ctx.model.joint_names();
        let mut with_winner = state.chosen.clone();
        with_winner.push(winner);
        let next = NormalEquations::over(
            model_columns(self.problem, &self.pool, &with_winner),
            &self.problem.y,
            dof,
            Rows::All,
        );
        let mut aliases = Vec::new();
        for (j, t) in tested {
            if *j == winner || state.status[*j].is_some() {
                continue;
            }
            let group: Vec<&Column> = self.pool[*j].columns.iter().collect();
            // Only what the winner leaves unexplained is read here, not the covariance.
            let after = test_group(&next, e0, &group, ctx.batching, &[]);
            if after.ok().map_or(0.0, |a| a.unexplained / t.unexplained) < ALIAS_LEFT {
                aliases.push(self.pool[*j].term.describe(&names));
                let reason = RejectionReason::AliasOf { label: self.pool[winner].term.describe(&names) };
                state.status[*j] = Some(rejection(ctx.model, &self.pool[*j].term, reason, Some(t.p_value), None));
            }
        }
        aliases
    }

    /// The joint fit of the declared model and the accepted effects, the errors before and
    /// after, the updated model, and the report.
    fn finish(
        &self,
        mut state: State,
        delay: isize,
        mut rejected: Vec<Rejection>,
        urdf: &str,
        source: &Source,
    ) -> Result<Diagnosis, DiagnoseError> {
        let (ctx, pool) = (self.ctx, &self.pool);
        let (model, dof) = (ctx.model, self.problem.dof);
        let kept = guard::keep_no_worse(ctx, delay, (self.problem, self.heldout), pool, &state.chosen);
        drop_reverted(&mut state, &kept, &mut rejected, model);
        unshift_delay(&mut state, &kept, &mut rejected, model);
        let (problem, heldout) = kept.rebuilt.as_ref().map_or((self.problem, self.heldout), |(p, h)| (p, h));
        let declared_only = model_columns(problem, pool, &[]);
        let final_cols = model_columns(problem, pool, &state.chosen);
        let given = ctx.given_coefficients(&kept.free);
        let x_before = match &given {
            Some(x) => x.clone(),
            None => least_squares(&declared_only, &problem.y, dof, Rows::All).ok_or(DiagnoseError::Singular)?,
        };
        let x_after = least_squares(&final_cols, &problem.y, dof, Rows::All).ok_or(DiagnoseError::Singular)?;
        // Coefficients of the effects from the joint fit (they moved as later effects came in).
        let from_gains = self.gain_errors.as_ref().and_then(|g| g.sigma(&final_cols, dof));
        let mut offset = declared_only.len();
        for (f, &i) in state.accepted.iter_mut().filter(|f| f.term.kind != EffectKind::Delay).zip(&state.chosen) {
            let width = pool[i].columns.len();
            f.term.coefficients = x_after[offset..offset + width].to_vec();
            if let Some(s) = &from_gains {
                f.share_of_gains(&s[offset..offset + width]);
            }
            f.weigh();
            offset += width;
        }
        // Before: the model the diagnosis started from, on the data as logged (no shift): the
        // given model as it is, or the declared model refitted.
        let before = match ctx.given_coefficients(&ctx.free) {
            Some(x) => as_given_summary(ctx, &x),
            None if delay == 0 => error_summary(self.problem, self.heldout, pool, &[]),
            None => error_summary(&ctx.problem(&ctx.train, 0), &ctx.heldout(0), pool, &[]),
        };
        let after = error_summary(problem, heldout, pool, &state.chosen);
        let declared_fit = Fitted { columns: &declared_only, coefficients: &x_before };
        let final_fit = Fitted { columns: &final_cols, coefficients: &x_after };
        let mut series = series(&ctx.train, problem, declared_fit, final_fit, pool, &state.chosen);
        // A start with laws of its own predicts with them (`Laws::Own`).
        if let (Some(x), true) = (&given, ctx.train.start_declared.is_some()) {
            let e = guard::as_given_residual(ctx, (&ctx.train, problem), x);
            series.residual_before = e.iter().enumerate().map(|(i, e)| e / problem.weights[i % dof]).collect();
        }
        let mut updated = self.updated_model(&state, (&kept.free, &x_after), &series, urdf, source)?;
        let source = match ctx.validation.is_some() {
            true => "the validation log".to_string(),
            false => format!(
                "the odd-numbered of {} blocks of {:.3} s, fitting on the even ones",
                ctx.split.count, ctx.split.block_s
            ),
        };
        updated.held_out = Some(crate::model_file::HeldOut {
            rms: after.heldout.rms.clone(),
            samples: heldout.samples(dof),
            cutoff_hz: ctx.train.pre.cutoff_hz,
            source: source.clone(),
            observer: None,
        });
        for (i, c) in pool.iter().enumerate().filter(|(i, _)| !state.chosen.contains(i)) {
            rejected.push(
                state.status[i]
                    .take()
                    .unwrap_or_else(|| rejection(model, &c.term, RejectionReason::NotReached, None, None)),
            );
        }
        let options = ctx.options;
        Ok(Diagnosis {
            format: "arash-diagnosis/1".into(),
            robot_name: model.name.clone(),
            joint_names: model.joint_names(),
            prismatic: model.joints.iter().map(|j| j.kind == JointKind::Prismatic).collect(),
            accepted: state.accepted,
            rejected,
            too_heavy: state.too_heavy,
            before,
            after,
            reverted: kept.reverted.iter().map(|(r, _)| r.clone()).collect(),
            still_worse: kept.worse.clone(),
            noise_floor: ctx.floor.rms.clone(),
            sensor_noise: ctx.floor.noise_rms.clone(),
            settings: DiagnoseSettings {
                cutoff_hz: ctx.train.pre.cutoff_hz,
                friction_cutoff_hz: Some(ctx.train.pre.friction_cutoff_hz),
                coulomb_epsilon: model.coulomb_laws.common().and_then(|s| s.epsilon()),
                friction_velocities: model.coulomb_laws.velocities(),
                reasons: ctx.train.pre.choices.reasons.clone(),
                warnings: ctx.train.pre.choices.warnings.clone(),
                decimate: ctx.train.stride(),
                block_s: ctx.split.block_s,
                blocks: ctx.split.count,
                batch_s: options.batch_s,
                alpha: options.alpha,
                min_gain: options.min_gain,
                max_vif: options.max_vif,
                max_delay_s: options.max_delay_s,
                refit: ctx.refit,
                started_from: if ctx.given.is_some() { StartedFrom::Given } else { StartedFrom::Declared },
                heldout: source,
                candidates: pool.len() + 1,
            },
            model: updated,
            series,
        })
    }

    /// The given model with its freed (friction) coefficients from the joint fit, or the
    /// refitted declared model; then the accepted effects.
    fn updated_model(
        &self,
        state: &State,
        (free, x_after): (&[bool], &[f64]),
        series: &Series,
        urdf: &str,
        source: &Source,
    ) -> Result<ModelFile, DiagnoseError> {
        let ctx = self.ctx;
        let mut updated = match ctx.given {
            Some(g) if !ctx.refit => g.clone(),
            _ => declared_model(ctx.model, ctx.base, urdf, &ctx.train, series, ctx.split.block_s, source)?,
        };
        if ctx.refit {
            // A refitted model is the OLS of `declared_model`, made with the effects taken out; a
            // given model's drive gains still turn its currents into torque.
            updated.drive_gains = ctx.given.and_then(|g| g.drive_gains.clone());
        } else {
            // Against a given model its freed (friction) coefficients take the joint fit's values,
            // which come first in `x_after`, in the order of the base parameters.
            let mut fitted = x_after.iter();
            if let Some(laws) = refitted_laws(ctx, free) {
                (updated.settings.coulomb_epsilon, updated.settings.friction_velocities) = Settings::law_fields(&laws);
            }
            let freed = updated.fitted.beta.iter_mut().zip(&ctx.base.independent).zip(free).filter(|(_, f)| **f);
            for ((b, j), _) in freed {
                *b = *fitted.next().expect("one coefficient per free column");
                // A refitted friction coefficient is a standard parameter of its own.
                if let Some(params) = updated.fitted.params.as_mut() {
                    params[*j] = *b;
                }
            }
        }
        updated.effects.extend(state.accepted.iter().flat_map(|f| model_terms(f, ctx.model.dof())));
        Ok(updated)
    }
}

/// Held against a given model with laws of the diagnosis's own: each joint whose friction was
/// refitted takes the law it was refitted with, and the others keep the given model's (`None`
/// where the two agree).
fn refitted_laws(ctx: &Context, free: &[bool]) -> Option<CoulombLaws> {
    let given = ctx.given?.coulomb_laws();
    if given == ctx.model.coulomb_laws {
        return None;
    }
    let shapes = (0..ctx.model.dof())
        .map(|k| match ctx.friction_refitted(k, free) {
            true => ctx.model.coulomb_laws.shape(k),
            false => given.shape(k),
        })
        .collect();
    Some(CoulombLaws::declared(shapes))
}

/// The accepted effects the guard dropped leave the findings for the rejections, with the joint
/// they made worse; the search's choice becomes the guard's.
fn drop_reverted(state: &mut State, kept: &guard::Kept, rejected: &mut Vec<Rejection>, model: &Model) {
    let names = model.joint_names();
    for (step, i) in kept.reverted.iter().filter_map(|(r, i)| i.map(|i| (r, i))) {
        let Some(at) = state.chosen.iter().position(|&c| c == i) else { continue };
        let finding = nth_effect(&state.accepted, at);
        let found = state.accepted.remove(finding);
        let sigmas = match &step.action {
            Reversion::DropEffect { sigmas, .. } => *sigmas,
            Reversion::HoldFriction | Reversion::Unshifted { .. } => {
                unreachable!("only a dropped effect has a pool index")
            }
        };
        rejected.push(worse_than_start(found, names[step.joint].clone(), sigmas));
        state.chosen.remove(at);
    }
    debug_assert_eq!(state.chosen, kept.chosen);
}

/// The rejection of an accepted finding the guard took away, for the harm it did to `joint`.
fn worse_than_start(found: Finding, joint: String, sigmas: f64) -> Rejection {
    Rejection {
        name: found.name,
        joints: found.joints,
        label: found.label,
        reason: RejectionReason::WorseThanStart { joint, sigmas },
        p_value: Some(found.p_value),
        heldout_gain: Some(found.heldout_gain),
    }
}

/// The delay's finding acts on the joints whose torque the guard left shifted; taken off every
/// joint, it leaves the findings for the rejections, with the joint it made worse last.
fn unshift_delay(state: &mut State, kept: &guard::Kept, rejected: &mut Vec<Rejection>, model: &Model) {
    let Some(at) = state.accepted.iter().position(|f| f.term.kind == EffectKind::Delay) else { return };
    let shifted: Vec<usize> = (0..kept.shifts.len()).filter(|&k| kept.shifts[k] != 0).collect();
    if shifted.len() == kept.shifts.len() {
        return;
    }
    let names = model.joint_names();
    if shifted.is_empty() {
        // Every joint was unshifted by a step of the guard; the last names the joint.
        let last = kept.reverted.iter().rev().find_map(|(r, _)| match r.action {
            Reversion::Unshifted { sigmas, .. } => Some((r.joint, sigmas)),
            _ => None,
        });
        let (joint, sigmas) = last.expect("a delay off every joint was taken off by the guard");
        rejected.push(worse_than_start(state.accepted.remove(at), names[joint].clone(), sigmas));
        return;
    }
    let finding = &mut state.accepted[at];
    finding.term.joint = (shifted.len() == 1).then(|| shifted[0]);
    finding.label = match finding.term.joint {
        Some(_) => finding.term.describe(&names),
        None => {
            // As a term on one joint reads: "delay on yaw, insertion (6 samples)".
            let on: Vec<&str> = shifted.iter().map(|&k| names[k].as_str()).collect();
            let (id, all) = (finding.term.kind.id(), finding.term.describe(&names));
            format!("{id} on {}{}", on.join(", "), &all[id.len()..])
        }
    };
    finding.joints = shifted;
}

/// The model file's terms of a finding: its term, or for a delay kept on some joints only, one
/// term per joint it shifts.
fn model_terms(f: &Finding, dof: usize) -> Vec<EffectTerm> {
    if f.term.kind != EffectKind::Delay || f.joints.len() == dof || f.joints.len() == 1 {
        return vec![f.term.clone()];
    }
    f.joints.iter().map(|&k| EffectTerm { joint: Some(k), ..f.term.clone() }).collect()
}

/// The index in `accepted` of the `at`-th effect that is not the delay (the delay has no columns
/// and no place in `chosen`).
fn nth_effect(accepted: &[Finding], at: usize) -> usize {
    accepted
        .iter()
        .enumerate()
        .filter(|(_, f)| f.term.kind != EffectKind::Delay)
        .nth(at)
        .map(|(i, _)| i)
        .expect("one finding per chosen effect")
}

/// The given model's errors as it is, on the data as logged: on every training sample, and on
/// the held-out samples.
fn as_given_summary(ctx: &Context, x: &[f64]) -> ErrorSummary {
    let (problem, heldout) = (ctx.problem(&ctx.train, 0), ctx.heldout(0));
    let e = guard::as_given_residual(ctx, (&ctx.train, &problem), x);
    let training = problem.metrics_of(&e, Rows::All);
    let heldout = match &heldout {
        HeldOut::Blocks { test, .. } => problem.metrics_of(&e, Rows::Where(test)),
        HeldOut::Validation(v) => {
            let data = ctx.validation.as_ref().expect("a validation problem comes from a validation log");
            v.metrics_of(&guard::as_given_residual(ctx, (data, v), x), Rows::All)
        }
    };
    ErrorSummary { training, heldout }
}

/// Two terms whose whole-robot held-out gains are within this ratio explain the data comparably.
const COMPARABLE_GAIN: f64 = 0.9;

/// Gains closer than this, relative to the larger, differ by round-off only: the two terms span
/// the same columns on this data (an offset and a Coulomb asymmetry on a joint that never stops).
const SAME_GAIN: f64 = 1e-9;

/// Of the candidates that passed, the one to add: the largest whole-robot gain, except that a
/// candidate with fewer columns within 10 % of it is preferred. A payload's four columns can
/// mimic an offset on one joint; the simpler explanation should win when the data cannot tell
/// them apart. Terms the data cannot tell apart at all go by the catalogue's order, which lists
/// the plainer explanation first, so that round-off does not choose between them.
fn most_useful(passing: &[Passed], width: impl Fn(usize) -> usize) -> Option<usize> {
    let best = passing.iter().map(|p| p.total).fold(f64::NEG_INFINITY, f64::max);
    let by_gain = |a: f64, b: f64| {
        if (a - b).abs() <= SAME_GAIN * a.abs().max(b.abs()) {
            std::cmp::Ordering::Equal
        } else {
            b.total_cmp(&a)
        }
    };
    (0..passing.len()).filter(|&i| passing[i].total >= COMPARABLE_GAIN * best).min_by(|&a, &b| {
        let (a, b) = (&passing[a], &passing[b]);
        width(a.test).cmp(&width(b.test)).then(by_gain(a.total, b.total)).then(a.test.cmp(&b.test))
    })
}

/// The first of `terms` (each with its number of columns, in the order of the fit `x`, whose
/// first `offset` coefficients are the model's) whose first coefficient has the sign its effect
/// cannot have, or does not exceed its floor (a drive gain of −1), with that coefficient. Terms
/// whose every coefficient is signed are left to their own test ([`wrong_sign`]).
fn first_flipped<'t>(
    terms: impl IntoIterator<Item = (&'t EffectTerm, usize)>,
    x: &[f64],
    mut offset: usize,
) -> Option<(&'t EffectTerm, f64)> {
    for (term, width) in terms {
        let flipped = !term.signs_every_coefficient() && term.wrong_sign_at(0, x[offset], 0.0);
        if flipped || term.below_floor_at(0, x[offset]).is_some() {
            return Some((term, x[offset]));
        }
        offset += width;
    }
    None
}

/// Why a payload's fit is no mass on its body, if it is not: a mass not told from zero, or a
/// centre of mass beyond the body's extent ([`Model::body_extent_m`]). Either sign: a mass taken
/// off is judged alike.
fn not_a_mass(term: &EffectTerm, t: &GroupTest, model: &Model) -> Option<RejectionReason> {
    if term.kind != EffectKind::Payload {
        return None;
    }
    let body = model.bodies.iter().position(|b| Some(&b.name) == term.body.as_ref())?;
    let reach_m = model.body_extent_m(body);
    let (mass, sigma) = (t.coefficients[0], t.sigma.first().copied().unwrap_or(f64::INFINITY));
    let rejected = |distance_m| RejectionReason::NotAMass {
        p_value: t.p_value,
        mass_kg: mass,
        mass_sigma_kg: sigma,
        distance_m,
        reach_m,
    };
    if mass.abs() <= PAYLOAD_MASS_SIGMAS * sigma {
        return Some(rejected(None));
    }
    let moments = t.coefficients[1..].iter().map(|c| c * c).sum::<f64>().sqrt();
    let distance = moments / mass.abs();
    (distance > reach_m).then(|| rejected(Some(distance)))
}

/// Why `term`'s fit is not its effect, if its first coefficient does not exceed the effect's floor
/// (a drive gain at or below −1).
fn below_floor(term: &EffectTerm, t: &GroupTest) -> Option<RejectionReason> {
    let &coefficient = t.coefficients.first()?;
    let (floor, why) = term.below_floor_at(0, coefficient)?;
    Some(RejectionReason::BelowFloor { p_value: t.p_value, coefficient, floor, why: why.to_string() })
}

/// The coefficient that gives `term` a sign its effect cannot have, if any: the first (a mass, a
/// friction), or where every coefficient is signed (rotor inertia on every joint, a coupled
/// rotor) any that is negative beyond two σ (one may be nil, none may be clearly negative).
fn wrong_sign(term: &EffectTerm, t: &GroupTest) -> Option<f64> {
    let slack = |i: usize| match term.signs_every_coefficient() {
        true => t.sigma.get(i).map_or(f64::INFINITY, |s| 2.0 * s),
        false => 0.0,
    };
    t.coefficients.iter().enumerate().find(|&(i, &c)| term.wrong_sign_at(i, c, slack(i))).map(|(_, &c)| c)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A payload is a mass on its body: its mass clear of zero by 2σ, either sign, and its centre
    /// of mass within the body's extent (here the tip's, the whole reach: 0.5 + 0.3 m of joint
    /// offsets and twice its 0.1 m centre of mass, 1.0 m). Other effects are not judged.
    #[test]
    fn a_payload_must_be_a_mass_on_its_body() {
        let urdf = r#"<robot name="t"><link name="base"/>
            <link name="l1"><inertial><origin xyz="0 0 0.1"/><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial></link>
            <link name="tip"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1"/></inertial></link>
            <joint name="a" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
            <joint name="b" type="revolute"><parent link="l1"/><child link="tip"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
            </robot>"#;
        let model = crate::urdf::parse_urdf(urdf).unwrap();
        let fit = |c: [f64; 4], sigma_m: f64| GroupTest {
            coefficients: c.to_vec(),
            sigma: vec![sigma_m, 1e-4, 1e-4, 1e-4],
            f_statistic: 100.0,
            p_value: 1e-9,
            unexplained: 0.5,
            batches: 50,
            batch_samples: 10,
        };
        let tip = crate::effects::payload_on("tip");
        let code = |t: &GroupTest| not_a_mass(&tip, t, &model).map(|r| r.code());
        assert_eq!(code(&fit([0.5, 0.0, 0.0, 0.25], 0.01)), None, "0.5 kg, 0.5 m out");
        assert_eq!(code(&fit([-0.5, 0.0, 0.0, -0.25], 0.01)), None, "taken off alike");
        assert_eq!(code(&fit([0.015, 0.0, 0.0, 0.0], 0.01)), Some("not_a_mass"), "1.5σ");
        assert_eq!(code(&fit([0.5, 0.0, 0.0, 0.55], 0.01)), Some("not_a_mass"), "1.1 m out");
        let Some(RejectionReason::NotAMass { distance_m, reach_m, .. }) =
            not_a_mass(&tip, &fit([0.5, 0.0, 0.0, 0.55], 0.01), &model)
        else {
            unreachable!()
        };
        assert!((distance_m.unwrap() - 1.1).abs() < 1e-12 && (reach_m - 1.0).abs() < 1e-12);
        let offset = EffectTerm::new(EffectKind::Offset, Some(0));
        assert!(not_a_mass(&offset, &fit([0.0; 4], 1.0), &model).is_none());
    }

    /// The narrower of two comparable terms wins; of two the data cannot tell apart (gains equal
    /// to round-off), the one the catalogue lists first, whichever round-off favours.
    #[test]
    fn ties_go_to_the_narrower_then_to_the_catalogue_order() {
        let passed = |test, total| Passed { test, gain: total, gains: vec![total], total, threshold: 0.01 };
        let one_column = |_| 1;
        let tied = [passed(0, 0.5), passed(1, 0.5 * (1.0 + 1e-12))];
        assert_eq!(most_useful(&tied, one_column), Some(0));
        let tied = [passed(1, 0.5 * (1.0 + 1e-12)), passed(0, 0.5)];
        assert_eq!(most_useful(&tied, one_column), Some(1), "by catalogue order, not by position");
        let apart = [passed(0, 0.5), passed(1, 0.6)];
        assert_eq!(most_useful(&apart, one_column), Some(1));
        let payload_wide = |test| if test == 1 { 4 } else { 1 };
        let comparable = [passed(0, 0.5), passed(1, 0.54)];
        assert_eq!(most_useful(&comparable, payload_wide), Some(0), "the narrower within 10 %");
        let clearly_more = [passed(0, 0.5), passed(1, 0.6)];
        assert_eq!(most_useful(&clearly_more, payload_wide), Some(1));
    }

    /// The coefficients of a fit sit after the model's, each term's after the one before; the
    /// sign is judged on each term's first, and a payload's other columns (its first moments)
    /// may have either sign.
    #[test]
    fn the_flipped_effect_is_found_at_its_own_offset() {
        let term = |kind, joint| EffectTerm::new(kind, joint);
        let offset = term(EffectKind::Offset, Some(0));
        let stribeck = term(EffectKind::Stribeck, Some(2));
        let payload = term(EffectKind::Payload, None);
        let armature = term(EffectKind::Armature, None);
        let terms = [(&offset, 1), (&payload, 4), (&armature, 3), (&stribeck, 1)];
        // Two model columns, then offset (any sign), payload m, m·c (any sign), armature, Stribeck.
        let mut x = vec![-9.0, -9.0, -1.0, 0.2, -1.0, -1.0, -1.0, -0.1, -0.1, -0.1, 0.3];
        assert!(first_flipped(terms, &x, 2).is_none());
        x[10] = -0.3;
        let (flipped, c) = first_flipped(terms, &x, 2).unwrap();
        assert_eq!((flipped.kind, c), (EffectKind::Stribeck, -0.3));
        x[3] = -0.2;
        assert_eq!(first_flipped(terms, &x, 2).unwrap().0.kind, EffectKind::Payload);
        // A drive gain has no sign, but its factor 1 + g must stay positive.
        let gain = EffectTerm::new(EffectKind::DriveGain, Some(1));
        assert!(first_flipped([(&gain, 1)], &[0.0, -0.9], 1).is_none());
        assert_eq!(
            first_flipped([(&gain, 1)], &[0.0, -1.04], 1).map(|(t, c)| (t.kind, c)),
            Some((EffectKind::DriveGain, -1.04))
        );
    }
}
