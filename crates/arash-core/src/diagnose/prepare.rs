//! A log made ready for the diagnosis: filtered, differentiated, trimmed and sampled, with the
//! declared model's columns and each candidate's columns on it.

use super::band::{noise_limited_cutoff, velocity_resolved_cutoff, Band, Positions};
use super::options::DiagnoseOptions;
use super::regression::Column;
use super::Runs;
use crate::base_parameters::BaseParameters;
use crate::data::Data;
use crate::effects::{EffectKind, EffectTerm, TermState};
use crate::identify::preprocess::{preprocess, PreprocessError, PreprocessOptions, Preprocessed};
use crate::model::Model;
use crate::regressor::regressor;

/// A log filtered and sampled for the diagnosis, with the declared model's columns.
pub(super) struct Prepared {
    pub(super) dof: usize,
    pub(super) fs: f64,
    pub(super) pre: Preprocessed,
    pub(super) q_raw: Vec<f64>,
    /// Full-rate sample indices used, every `stride`-th inside the trimmed ends.
    pub(super) kept: Vec<usize>,
    /// Base-parameter columns, unweighted.
    pub(super) declared: Vec<Column>,
    /// Mass and first-moment columns of each body with mass: (body, columns).
    pub(super) bodies: Vec<(usize, Vec<Column>)>,
    /// The declared model's torque at the kept samples (`kept × dof`), once it is fitted: what a
    /// drive's gain scales.
    pub(super) predicted: Vec<f64>,
}

impl Prepared {
    pub(super) fn samples(&self) -> usize {
        self.kept.len()
    }

    /// Full-rate samples between kept ones.
    pub(super) fn stride(&self) -> usize {
        self.kept.get(1).map_or(1, |k| k - self.kept[0])
    }

    /// Kept samples per second.
    pub(super) fn kept_rate(&self) -> f64 {
        self.fs / self.stride() as f64
    }

    /// The filtered torque at the kept samples, shifted by `delay` full-rate samples.
    pub(super) fn tau(&self, delay: isize) -> Vec<f64> {
        let dof = self.dof;
        let mut out = Vec::with_capacity(self.kept.len() * dof);
        for &i in &self.kept {
            let j = (i as isize + delay) as usize;
            out.extend_from_slice(&self.pre.tau[j * dof..(j + 1) * dof]);
        }
        out
    }

    pub(super) fn at_kept(&self, x: &[f64]) -> Vec<f64> {
        let dof = self.dof;
        self.kept.iter().flat_map(|&i| x[i * dof..(i + 1) * dof].iter().copied()).collect()
    }
}

impl Prepared {
    pub(super) fn band(&self) -> Band {
        Band { cutoff_hz: self.pre.cutoff_hz, friction_hz: self.pre.friction_cutoff_hz }
    }
}

/// Prepare `log` for the diagnosis: filtered in `band` (a training log's), or at the user's
/// cut-off, or at the diagnosis's; its Coulomb columns switching with the velocity filtered at
/// the band's friction cut-off, the user's, or the cut-off slowed where the encoder's steps would
/// blur it ([`velocity_resolved_cutoff`]); and trimmed by `margin_s` at each end and on both
/// sides of each run's start (held-out runs joined end to end).
///
/// The friction velocity is not chosen by the fit here, as identification chooses it: the
/// diagnosis's decision rule was calibrated with it at the diagnosis's cut-off, and on the demo's
/// closed-loop log the fit's choice (16 Hz against 20) moves the insertion's residual enough for
/// two spurious terms to pass the held-out gain threshold (docs/diagnosis.md).
pub(super) fn prepare(
    model: &Model,
    base: &BaseParameters,
    Runs { log, starts }: Runs,
    (options, band): (&DiagnoseOptions, Option<Band>),
    margin_s: f64,
) -> Result<Prepared, PreprocessError> {
    let dof = model.dof();
    let dt = crate::identify::preprocess::validate_log(log.t, log.q, log.tau, dof)?;
    let fs = 1.0 / dt;
    let default = DiagnoseOptions::default_cutoff_hz(fs);
    let order = options.preprocess.order;
    // Read from the positions once, by whichever of the band's rules runs first.
    let positions = std::cell::OnceCell::new();
    let positions = || positions.get_or_init(|| Positions::of(log.q, (dof, fs)));
    let mut warning = None;
    let (cutoff, reason) = match (options.preprocess.cutoff_hz, band) {
        (Some(user), _) => (user, None),
        (None, Some(band)) => {
            let cutoff = band.cutoff_hz.min(default);
            (cutoff, Some(format!("cut-off {cutoff:.3} Hz: the training log's, at most {default:.2} Hz")))
        }
        (None, None) => {
            let chosen = noise_limited_cutoff(positions(), order)?;
            warning = chosen.warning;
            (chosen.cutoff_hz, Some(chosen.reason))
        }
    };
    let (friction, friction_reason) = match (band, options.preprocess.friction_cutoff_hz) {
        (Some(band), _) => (Some(band.friction_hz), None),
        (None, Some(user)) => (Some(user), None),
        (None, None) => {
            let chosen = velocity_resolved_cutoff(positions(), cutoff, order)?;
            (Some(chosen.cutoff_hz), Some(chosen.reason))
        }
    };
    let pre_options = PreprocessOptions { friction_cutoff_hz: friction, ..options.preprocessing(cutoff) };
    let mut pre = preprocess(log.t, log.q, log.tau, dof, &pre_options)?;
    for (prefix, line) in [("cut-off", reason), ("Coulomb", friction_reason)] {
        if let Some(line) = line {
            pre.choices.reasons.iter_mut().filter(|r| r.starts_with(prefix)).for_each(|r| *r = line.clone());
        }
    }
    pre.choices.warnings.extend(warning);
    let stride = stride(options, fs, pre.cutoff_hz);
    let n = pre.samples();
    let margin = ((margin_s * fs).ceil() as usize).max(pre.settled.start);
    let needed = 2 * margin + MIN_KEPT * stride;
    if n < needed {
        return Err(PreprocessError::TooFewSamples { needed, got: n });
    }
    // Where one run ends and the next begins, the filter's transient spans both sides.
    let clear = |i: usize| starts.iter().all(|&s| i + margin < s || i >= s + margin);
    let kept: Vec<usize> = (margin..n - margin).step_by(stride).filter(|&i| clear(i)).collect();
    if kept.len() < MIN_KEPT {
        return Err(PreprocessError::TooFewSamples { needed: needed + 2 * margin * starts.len(), got: n });
    }
    let (declared, bodies) = declared_columns(model, base, &pre, &kept);
    Ok(Prepared { dof, fs, pre, q_raw: log.q.to_vec(), kept, declared, bodies, predicted: vec![] })
}

/// The fewest samples a diagnosis keeps.
const MIN_KEPT: usize = 64;

/// Full-rate samples between kept ones at `cutoff_hz`: the user's, or about five per cut-off
/// period.
fn stride(options: &DiagnoseOptions, fs: f64, cutoff_hz: f64) -> usize {
    options.decimate.unwrap_or(((fs / (5.0 * cutoff_hz)).floor() as usize).max(1)).max(1)
}

/// Column `c` of a body's mass and first-moment columns, or exact zeros where it is round-off
/// beside the others (a first moment along an axis the body turns about): the regression pins
/// such a column's coefficient to zero instead of fitting noise with it.
pub(super) fn visible(columns: &[Vec<f64>], c: usize) -> Vec<f64> {
    let size = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let largest = columns.iter().map(|v| size(v)).fold(0.0, f64::max);
    if size(&columns[c]) <= 1e-9 * largest {
        vec![0.0; columns[c].len()]
    } else {
        columns[c].clone()
    }
}

/// The base-parameter columns at the kept samples, Coulomb columns filtered like the torque (as
/// identification does), and each body's mass and first-moment columns (payload candidates).
pub(super) fn declared_columns(
    model: &Model,
    base: &BaseParameters,
    pre: &Preprocessed,
    kept: &[usize],
) -> (Vec<Column>, Vec<(usize, Vec<Column>)>) {
    let dof = model.dof();
    let mut columns = full_columns(model, pre, kept);
    let layout = model.layout();
    let bodies = (0..model.bodies.len())
        .filter(|&b| columns[layout.body(b).start].iter().any(|v| *v != 0.0))
        .map(|b| {
            let mass_and_moments = &columns[layout.mass_and_moments(b)];
            (b, (0..mass_and_moments.len()).map(|c| Column::dense(visible(mass_and_moments, c), dof)).collect())
        })
        .collect();
    let declared = base.independent.iter().map(|&j| Column::dense(std::mem::take(&mut columns[j]), dof)).collect();
    (declared, bodies)
}

/// All P standard-parameter columns at the kept samples (`kept × dof` rows each), the Coulomb
/// columns filtered like the torque.
pub(super) fn full_columns(model: &Model, pre: &Preprocessed, kept: &[usize]) -> Vec<Vec<f64>> {
    let (dof, big_p) = (model.dof(), model.num_params());
    let mut columns = vec![vec![0.0; kept.len() * dof]; big_p];
    let mut data = Data::new(model);
    let mut y = vec![0.0; dof * big_p];
    for (s, &i) in kept.iter().enumerate() {
        let range = i * dof..(i + 1) * dof;
        regressor(model, &mut data, &pre.q[range.clone()], &pre.qd[range.clone()], &pre.qdd[range], &mut y);
        for k in 0..dof {
            for (j, column) in columns.iter_mut().enumerate() {
                column[s * dof + k] = y[k * big_p + j];
            }
        }
    }
    let coulomb = pre.coulomb_columns(model.coulomb_shape);
    for k in 0..dof {
        let j = model.layout().coulomb(k);
        for (s, &i) in kept.iter().enumerate() {
            columns[j][s * dof + k] = coulomb[i * dof + k];
        }
    }
    columns
}

/// The columns of `term` on a prepared log.
pub(super) fn term_columns(model: &Model, term: &EffectTerm, data: &Prepared) -> Vec<Column> {
    let dof = data.dof;
    if term.kind == EffectKind::Payload {
        let body = model.bodies.iter().position(|b| Some(&b.name) == term.body.as_ref());
        return data.bodies.iter().find(|(b, _)| Some(*b) == body).map(|(_, c)| c.clone()).unwrap_or_default();
    }
    let Some(k) = term.joint else {
        if term.kind == EffectKind::Armature {
            return (0..dof)
                .map(|k| Column::Joint(k, data.kept.iter().map(|&i| data.pre.qdd[i * dof + k]).collect()))
                .collect();
        }
        return vec![];
    };
    let width = term.width();
    let filtered: Vec<bool> = (0..width).map(|c| term.column_filtered(c)).collect();
    let mut columns = vec![Vec::with_capacity(data.samples()); width];
    if filtered.contains(&true) {
        for (c, values) in filtered_term_columns(term, data).into_iter().enumerate().filter(|(c, _)| filtered[*c]) {
            columns[c] = values;
        }
    }
    if filtered.contains(&false) {
        let pre = &data.pre;
        let (mut state, mut out, zeros) = (TermState::default(), vec![0.0; width], vec![0.0; dof]);
        for (s, &i) in data.kept.iter().enumerate() {
            let row = i * dof..(i + 1) * dof;
            let tau = data.predicted.get(s * dof..(s + 1) * dof).unwrap_or(&zeros);
            let x = term.sample_of(&pre.q[row.clone()], &pre.qd[row.clone()], &pre.qdd[row], pre.t[i], tau);
            term.features(x.expect("a term on a joint"), &mut state, &mut out);
            for c in (0..width).filter(|c| !filtered[*c]) {
                columns[c].push(out[c]);
            }
        }
    }
    match term.coupling {
        None => columns.into_iter().map(|v| Column::Joint(k, v)).collect(),
        // A coupled rotor's torque acts on every joint its motor turns with.
        Some(_) => columns
            .into_iter()
            .map(|v| Column::dense((0..v.len() * dof).map(|r| term.weight_on(r % dof) * v[r / dof]).collect(), dof))
            .collect(),
    }
}

/// Every column of `term` computed at every sample from the unfiltered position and the
/// friction velocity, then filtered like the torque, at the kept samples.
fn filtered_term_columns(term: &EffectTerm, data: &Prepared) -> Vec<Vec<f64>> {
    let (dof, width, pre) = (data.dof, term.width(), &data.pre);
    let n = pre.samples();
    let (mut state, mut out, zeros) = (TermState::default(), vec![0.0; width], vec![0.0; dof]);
    let mut full = vec![0.0; n * width];
    for s in 0..n {
        let row = s * dof..(s + 1) * dof;
        let x = term.sample_of(&data.q_raw[row.clone()], &pre.qd_friction[row], &zeros, pre.t[s], &zeros);
        term.features(x.expect("a term on a joint"), &mut state, &mut out);
        full[s * width..(s + 1) * width].copy_from_slice(&out);
    }
    let filtered = pre.filter_like_torque(&full, width).expect("the torque was filtered with these settings");
    (0..width).map(|c| data.kept.iter().map(|&i| filtered[i * width + c]).collect()).collect()
}
