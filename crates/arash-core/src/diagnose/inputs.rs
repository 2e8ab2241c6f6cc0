//! What every step of a diagnosis shares: the prepared logs, which declared columns are fitted,
//! the joint weights and the blocks of time.

use super::band::Band;
use super::band_choice::BandChoice;
use super::noise::{HeldOutTorque, NoiseFloor};
use super::options::{DiagnoseError, DiagnoseOptions};
use super::prepare::{declared_columns, prepare, term_columns, Prepared};
use super::regression::{self, least_squares, residual, Batching, Column, Rows};
use super::weighted_fit::{heldout_split, heldout_sse, Candidate, HeldOut, Problem, Split};
use super::Runs;
use crate::base_parameters::BaseParameters;
use crate::effects::{EffectKind, EffectTerm};
use crate::model::Model;
use crate::model_file::ModelFile;
use crate::signal::filter::Butterworth;
use crate::signal::log::Log;

/// The prepared logs and what every step of the search shares: which declared columns are
/// fitted, the joint weights and the blocks of time.
pub(super) struct Context<'a> {
    pub(super) model: &'a Model,
    pub(super) base: &'a BaseParameters,
    pub(super) given: Option<&'a ModelFile>,
    pub(super) options: &'a DiagnoseOptions,
    pub(super) train: Prepared,
    pub(super) validation: Option<Prepared>,
    /// Whether the declared base parameters are refitted (no model given, or `refit`).
    pub(super) refit: bool,
    /// Which declared columns are fitted (the others are held at the given model's values).
    pub(super) free: Vec<bool>,
    /// Per joint, 1 / RMS of the declared model's residual: N·m and N do not mix.
    pub(super) weights: Vec<f64>,
    /// The held-out split of the training log's kept samples, guarded by the filter's memory.
    pub(super) split: Split,
    /// How the Wald test cuts the training samples into batches.
    pub(super) batching: Batching,
    /// The held-out torque's noise floor, which held-out gains are judged above.
    pub(super) floor: NoiseFloor,
}

impl<'a> Context<'a> {
    pub(super) fn new(
        model: &'a Model,
        base: &'a BaseParameters,
        train: Log,
        validation: Option<Runs>,
        given: Option<&'a ModelFile>,
        options: &'a DiagnoseOptions,
        choice: &BandChoice,
    ) -> Result<Self, DiagnoseError> {
        let margin = options.max_delay_s;
        let band = choice.band;
        let (train_log, validation_runs) = (train, validation);
        let mut train = prepare(model, base, train.into(), options, band, margin).map_err(DiagnoseError::Training)?;
        let choices = &mut train.pre.choices;
        choices.reasons.retain(|r| !r.is_cutoff() && !r.is_friction());
        choices.reasons.extend(choice.reasons.iter().cloned());
        choices.warnings.extend(choice.warnings.iter().cloned());
        // The held-out log is filtered in the band chosen on the training log.
        let mut validation = validation
            .map(|v| prepare(model, base, v, options, band, margin))
            .transpose()
            .map_err(DiagnoseError::Validation)?;
        if let Some(g) = given {
            g.controller_parameters(model)?;
            if g.base_independent != base.independent {
                return Err(DiagnoseError::BaseMismatch);
            }
            // A start with laws of its own predicts with them, on every log, once.
            let laws = g.coulomb_laws();
            if laws != model.coulomb_laws {
                let with_its_laws = Model { coulomb_laws: laws, ..model.clone() };
                for data in std::iter::once(&mut train).chain(validation.as_mut()) {
                    data.start_declared = Some(declared_columns(&with_its_laws, base, &data.pre, &data.kept).0);
                }
            }
        }
        let refit = given.is_none() || options.refit;
        // Against a given model, friction is refitted all the same: it drifts with temperature,
        // and its coefficients depend on how the velocity that switches it was estimated.
        let friction = model.layout().friction();
        let free = base.independent.iter().map(|j| refit || (friction.contains(j) && !options.hold_friction)).collect();
        let filter = Butterworth::lowpass(options.preprocess.order, band.cutoff_hz, train.fs)
            .map_err(|e| DiagnoseError::Training(e.into()))?;
        let split = heldout_split(&train.kept, train.fs, options.block_s, filter.memory_s(train.fs));
        let batching = options
            .batch_s
            .map_or(Batching::FromScores, |s| Batching::Fixed(((s * train.kept_rate()).round() as usize).max(1)));
        let mut ctx = Self {
            model,
            base,
            given,
            options,
            train,
            validation,
            refit,
            free,
            weights: vec![1.0; model.dof()],
            split,
            batching,
            floor: NoiseFloor::none(model.dof()),
        };
        let (x, weights) = ctx.declared_fit()?;
        ctx.weights = weights;
        ctx.floor = ctx.noise_floor((train_log, validation_runs), choice.narrowest)?;
        ctx.train.predicted = ctx.declared_torque(&ctx.train, &x);
        let validation = ctx.validation.as_ref().map(|v| ctx.declared_torque(v, &x));
        if let (Some(v), Some(predicted)) = (ctx.validation.as_mut(), validation) {
            v.predicted = predicted;
        }
        Ok(ctx)
    }

    /// The floor of the held-out error: the torque's white noise in the band, and what the band
    /// holds above `narrowest`, the narrowest that predicts as well ([`NoiseFloor::above`]), where
    /// the band is wider. `logs` are the training log and the held-out runs, to filter there.
    fn noise_floor(&self, logs: (Log, Option<Runs>), narrowest: Band) -> Result<NoiseFloor, DiagnoseError> {
        let here = self.white_floor(&self.train, self.validation.as_ref(), &self.split)?;
        if narrowest.cutoff_hz >= self.train.pre.cutoff_hz {
            return Ok(here);
        }
        let (options, margin) = (self.options, self.options.max_delay_s);
        let train = prepare(self.model, self.base, logs.0.into(), options, narrowest, margin)
            .map_err(DiagnoseError::Training)?;
        let validation = logs
            .1
            .map(|v| prepare(self.model, self.base, v, options, narrowest, margin))
            .transpose()
            .map_err(DiagnoseError::Validation)?;
        let memory = Butterworth::lowpass(options.preprocess.order, narrowest.cutoff_hz, train.fs)
            .map_err(|e| DiagnoseError::Training(e.into()))?
            .memory_s(train.fs);
        let split = heldout_split(&train.kept, train.fs, options.block_s, memory);
        let heldout = match &validation {
            Some(v) => HeldOut::Validation(self.problem(v, 0)),
            None => HeldOut::Blocks { train: split.train.clone(), test: split.test.clone() },
        };
        let before_here = heldout_sse(&self.problem(&self.train, 0), &self.heldout(0), &[], &[]);
        let at_narrowest = self.white_floor(&train, validation.as_ref(), &split)?;
        let before_narrowest = heldout_sse(&self.problem(&train, 0), &heldout, &[], &[]);
        Ok(here.above(&before_here, &before_narrowest, &at_narrowest))
    }

    /// The torque's white noise in `train`'s band on its held-out samples: the validation log's,
    /// or the odd blocks of `split`.
    fn white_floor(
        &self,
        train: &Prepared,
        validation: Option<&Prepared>,
        split: &Split,
    ) -> Result<NoiseFloor, DiagnoseError> {
        let (data, samples) = match validation {
            Some(v) => (v, v.samples()),
            None => (train, split.test.iter().filter(|t| **t).count()),
        };
        let duration_s = (samples * data.stride()) as f64 / data.fs;
        NoiseFloor::of(HeldOutTorque {
            tau: &data.pre.tau_unfiltered,
            dof: data.dof,
            fs: data.fs,
            order: self.options.preprocess.order,
            cutoff_hz: data.pre.cutoff_hz,
            weights: &self.weights,
            samples,
            duration_s,
        })
        .map_err(|e| DiagnoseError::Training(e.into()))
    }

    /// The largest shift of the delay search (samples).
    pub(super) fn max_shift(&self) -> isize {
        (self.options.max_delay_s * self.train.fs).round() as isize
    }

    /// What the given model's held parameters and effects predict on `data` (zero when refitting),
    /// with the declared columns `free` fitted and the others held.
    pub(super) fn fixed_prediction(&self, data: &Prepared, free: &[bool]) -> Vec<f64> {
        let dof = data.dof;
        let mut pred = vec![0.0; data.samples() * dof];
        if let (Some(g), false) = (self.given, self.refit) {
            // The held columns at the given model's coefficients, with its own laws where the
            // diagnosis chose others.
            let columns = data.start_declared.as_ref().unwrap_or(&data.declared);
            for ((c, b), _) in columns.iter().zip(&g.fitted.beta).zip(free).filter(|(_, f)| !**f) {
                regression::axpy(&mut pred, *b, c, dof);
            }
            for term in g.effects.iter().filter(|t| t.kind != EffectKind::DriveGain) {
                for (c, x) in term_columns(self.model, term, data).iter().zip(&term.coefficients) {
                    regression::axpy(&mut pred, *x, c, dof);
                }
            }
            // A drive's gain scales what the rest of the given model predicts (its held part: the
            // refitted friction is fitted to the measured torque, gain and all).
            let factors = self.given_gain_factors();
            pred.iter_mut().enumerate().for_each(|(i, p)| *p *= factors[i % dof]);
        }
        pred
    }

    /// The declared model's free coefficients fitted to the training log, unweighted, and the
    /// joint weights: 1 / RMS per joint of that fit's residual.
    fn declared_fit(&self) -> Result<(Vec<f64>, Vec<f64>), DiagnoseError> {
        let dof = self.model.dof();
        let unit = self.problem(&self.train, 0);
        let cols: Vec<&Column> = unit.free_columns().collect();
        let x = least_squares(&cols, &unit.y, dof, Rows::All).ok_or(DiagnoseError::Singular)?;
        let e = residual(&cols, &x, &unit.y, dof);
        let n = self.train.samples() as f64;
        let weights = (0..dof)
            .map(|k| {
                let rms = (e.iter().skip(k).step_by(dof).map(|v| v * v).sum::<f64>() / n).sqrt();
                if rms > 0.0 {
                    1.0 / rms
                } else {
                    1.0
                }
            })
            .collect();
        Ok((x, weights))
    }

    /// The declared model's torque on `data`: the given model's held part and the free
    /// coefficients `x`.
    fn declared_torque(&self, data: &Prepared, x: &[f64]) -> Vec<f64> {
        let mut torque = self.fixed_prediction(data, &self.free);
        let free = data.declared.iter().zip(&self.free).filter(|(_, f)| **f).map(|(c, _)| c);
        for (column, coefficient) in free.zip(x) {
            regression::axpy(&mut torque, *coefficient, column, data.dof);
        }
        torque
    }

    /// The weighted problem on `data` with the torque shifted by `delay` samples.
    pub(super) fn problem(&self, data: &Prepared, delay: isize) -> Problem {
        self.problem_with(data, &vec![delay; data.dof], &self.free)
    }

    /// [`Self::problem`] with each joint's torque shifted by its own `shifts[k]` samples, the
    /// declared columns `free` fitted and the others held at the given model's values.
    pub(super) fn problem_with(&self, data: &Prepared, shifts: &[isize], free: &[bool]) -> Problem {
        Problem::new(data, data.tau_shifted(shifts), self.fixed_prediction(data, free), &self.weights, free)
    }

    /// Where held-out errors are measured, with the torque shifted by `delay` samples.
    pub(super) fn heldout(&self, delay: isize) -> HeldOut {
        self.heldout_with(&vec![delay; self.model.dof()], &self.free)
    }

    /// [`Self::heldout`] with each joint's torque shifted by `shifts[k]` and the declared columns
    /// `free` fitted.
    pub(super) fn heldout_with(&self, shifts: &[isize], free: &[bool]) -> HeldOut {
        match &self.validation {
            Some(v) => HeldOut::Validation(self.problem_with(v, shifts, free)),
            None => HeldOut::Blocks { train: self.split.train.clone(), test: self.split.test.clone() },
        }
    }

    /// The given model's coefficients of the declared columns `free`: its prediction as it is, on
    /// a problem built with `free` (refitting, every declared column is free, and the given
    /// model's effects other than drive gains are not part of it).
    pub(super) fn given_coefficients(&self, free: &[bool]) -> Option<Vec<f64>> {
        let g = self.given?;
        Some(g.fitted.beta.iter().zip(free).filter(|(_, f)| **f).map(|(b, _)| *b).collect())
    }

    /// Per joint, the factor the given model's drive gains scale its prediction by (1 where it
    /// has none).
    pub(super) fn given_gain_factors(&self) -> Vec<f64> {
        let mut factors = vec![1.0; self.model.dof()];
        for term in self.given.iter().flat_map(|g| &g.effects).filter(|t| t.kind == EffectKind::DriveGain) {
            if let (Some(k), Some(gain)) = (term.joint, term.coefficients.first()) {
                factors[k] *= 1.0 + gain;
            }
        }
        factors
    }

    /// Whether any of joint `k`'s friction columns is among the fitted columns `free`.
    pub(super) fn friction_refitted(&self, k: usize, free: &[bool]) -> bool {
        self.friction_columns_of(k).iter().zip(free).any(|(c, f)| *c && *f)
    }

    /// The declared columns of joint `k`'s friction.
    pub(super) fn friction_columns_of(&self, k: usize) -> Vec<bool> {
        let layout = self.model.layout();
        self.base.independent.iter().map(|&j| j == layout.viscous(k) || j == layout.coulomb(k)).collect()
    }

    /// Each template's weighted columns on the training log (and the validation log); templates
    /// without columns on this data are dropped.
    pub(super) fn pool(&self, templates: Vec<EffectTerm>, problem: &Problem, heldout: &HeldOut) -> Vec<Candidate> {
        crate::parallel::map(templates, |term| self.candidate(term, problem, heldout))
            .into_iter()
            .filter(|c| !c.columns.is_empty())
            .collect()
    }

    /// One term's weighted columns on the training log (and the validation log).
    pub(super) fn candidate(&self, term: EffectTerm, problem: &Problem, heldout: &HeldOut) -> Candidate {
        let columns = self.training_columns(&term, problem);
        let validation = match (heldout, &self.validation) {
            (HeldOut::Validation(p), Some(v)) => p.weighted(term_columns(self.model, &term, v)),
            _ => vec![],
        };
        Candidate { term, columns, validation }
    }

    /// One term's weighted columns on the training log alone.
    pub(super) fn training_columns(&self, term: &EffectTerm, problem: &Problem) -> Vec<Column> {
        problem.weighted(term_columns(self.model, term, &self.train))
    }
}
