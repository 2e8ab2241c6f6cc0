//! A log made ready for the diagnosis: filtered, differentiated, trimmed and sampled, with the
//! declared model's columns and each candidate's columns on it.

use super::band::Band;
use super::options::DiagnoseOptions;
use super::regression::Column;
use super::Runs;
use crate::base_parameters::BaseParameters;
use crate::data::Data;
use crate::effects::{EffectKind, EffectTerm, TermState};
use crate::model::Model;
use crate::regressor::regressor;
use crate::signal::log::Log;
use crate::signal::options::PreprocessOptions;
use crate::signal::preprocess::{preprocess, PreprocessError, Preprocessed, EDGE_CUTOFF_PERIODS};

/// A log filtered and sampled for the diagnosis, with the declared model's columns.
pub(super) struct Prepared {
    pub(super) dof: usize,
    pub(super) fs: f64,
    pub(super) pre: Preprocessed,
    pub(super) q_raw: Vec<f64>,
    /// Full-rate sample indices used, every `stride`-th inside the trimmed ends.
    pub(super) kept: Vec<usize>,
    /// The full-rate sample at which each run after the first begins (held-out runs joined).
    pub(super) starts: Vec<usize>,
    /// The given model's declared columns with its own Coulomb laws, where the diagnosis fits
    /// with others (`Laws::Own`): what its prediction as it is needs.
    pub(super) start_declared: Option<Vec<Column>>,
    /// Base-parameter columns, unweighted.
    pub(super) declared: Vec<Column>,
    /// The ten inertial columns of each body with mass (payload candidates): (body, columns).
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
        self.tau_shifted(&vec![delay; self.dof])
    }

    /// [`Self::tau`] with each joint's torque shifted by its own `shifts[k]` samples.
    pub(super) fn tau_shifted(&self, shifts: &[isize]) -> Vec<f64> {
        let dof = self.dof;
        let mut out = Vec::with_capacity(self.kept.len() * dof);
        for &i in &self.kept {
            out.extend(shifts.iter().enumerate().map(|(k, d)| self.pre.tau[(i as isize + d) as usize * dof + k]));
        }
        out
    }

    /// The kept samples of each run, as ranges of kept indices, in order.
    pub(super) fn runs(&self) -> Vec<std::ops::Range<usize>> {
        let mut bounds: Vec<usize> = self.starts.iter().map(|&s| self.kept.partition_point(|&i| i < s)).collect();
        bounds.insert(0, 0);
        bounds.push(self.kept.len());
        bounds.windows(2).filter(|w| w[1] > w[0]).map(|w| w[0]..w[1]).collect()
    }

    pub(super) fn at_kept(&self, x: &[f64]) -> Vec<f64> {
        let dof = self.dof;
        self.kept.iter().flat_map(|&i| x[i * dof..(i + 1) * dof].iter().copied()).collect()
    }
}

impl Prepared {
    /// The declared model's columns of `pre` (a log filtered for the diagnosis, its raw positions
    /// `q_raw`) at the samples `kept`.
    pub(super) fn new(
        model: &Model,
        base: &BaseParameters,
        pre: Preprocessed,
        q_raw: &[f64],
        kept: Vec<usize>,
    ) -> Self {
        let fs = pre.sample_rate_hz;
        let (declared, bodies) = declared_columns(model, base, &pre, &kept);
        let (dof, q_raw) = (model.dof(), q_raw.to_vec());
        Prepared {
            dof,
            fs,
            pre,
            q_raw,
            kept,
            starts: vec![],
            start_declared: None,
            declared,
            bodies,
            predicted: vec![],
        }
    }
}

/// `log` filtered in `band` for the diagnosis: the user's other settings, no averaging, and the
/// Coulomb columns switching with the velocity filtered at the band's friction cut-off.
pub(super) fn filtered(
    log: Log,
    dof: usize,
    options: &DiagnoseOptions,
    band: Band,
) -> Result<Preprocessed, PreprocessError> {
    let pre_options =
        PreprocessOptions { friction_cutoff_hz: Some(band.friction_hz), ..options.preprocessing(band.cutoff_hz) };
    preprocess(log.t, log.q, log.tau, dof, &pre_options)
}

/// The samples a diagnosis keeps of `pre`: every `stride`-th, clear of the filter's start-up
/// transient (and of `margin_s`) at the ends and on both sides of each run's start in `starts`
/// (held-out runs joined end to end).
pub(super) fn kept_samples(
    pre: &Preprocessed,
    margin_s: f64,
    starts: &[usize],
    stride: usize,
) -> Result<Vec<usize>, PreprocessError> {
    let n = pre.samples();
    let margin = ((margin_s * pre.sample_rate_hz).ceil() as usize).max(pre.settled.start);
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
    Ok(kept)
}

/// Prepare `log` for the diagnosis: filtered in `band` ([`filtered`]), and kept every
/// [`stride`]-th sample clear of the ends and of each run's start ([`kept_samples`]), with the
/// declared model's columns there.
pub(super) fn prepare(
    model: &Model,
    base: &BaseParameters,
    Runs { log, starts }: Runs,
    options: &DiagnoseOptions,
    band: Band,
    margin_s: f64,
) -> Result<Prepared, PreprocessError> {
    let dof = model.dof();
    crate::signal::preprocess::validate_log(log.t, log.q, log.tau, dof)?;
    let pre = filtered(log, dof, options, band)?;
    let stride = stride(options, pre.sample_rate_hz, pre.cutoff_hz);
    let kept = kept_samples(&pre, margin_s, starts, stride)?;
    let mut prepared = Prepared::new(model, base, pre, log.q, kept);
    prepared.starts = starts.to_vec();
    Ok(prepared)
}

/// The fewest samples a diagnosis keeps.
const MIN_KEPT: usize = 64;

/// Kept samples per cut-off period, where the user sets no thinning.
const KEPT_PER_PERIOD: f64 = 5.0;

/// The lowest cut-off at which a log of `samples` at `fs` keeps [`MIN_KEPT`] samples between the
/// filter's start-up transients (and `margin_s`) at its ends.
pub(super) fn lowest_kept_cutoff_hz(samples: usize, fs: f64, margin_s: f64) -> f64 {
    let periods = 2.0 * EDGE_CUTOFF_PERIODS + MIN_KEPT as f64 / KEPT_PER_PERIOD;
    periods * fs / (samples as f64 - 2.0 * margin_s * fs).max(1.0)
}

/// Full-rate samples between kept ones at `cutoff_hz`: the user's, or about five per cut-off
/// period.
pub(super) fn stride(options: &DiagnoseOptions, fs: f64, cutoff_hz: f64) -> usize {
    options.decimate.unwrap_or(((fs / (KEPT_PER_PERIOD * cutoff_hz)).floor() as usize).max(1)).max(1)
}

/// Column `c` of a body's inertial columns, or exact zeros where it is round-off beside the
/// others (a first moment along an axis the body turns about): the regression pins
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
/// identification does), and each body's ten inertial columns (payload candidates).
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
            let inertial = &columns[layout.body(b)];
            (b, (0..inertial.len()).map(|c| Column::dense(visible(inertial, c), dof)).collect())
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
    let coulomb = pre.coulomb_columns(&model.coulomb_laws);
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
        // Its mass and first moments, and its inertia where the term carries it.
        let width = term.columns.len().clamp(term.width(), crate::params::PER_BODY);
        let of_body = data.bodies.iter().find(|(b, _)| Some(*b) == body);
        return of_body.map(|(_, c)| c[..width].to_vec()).unwrap_or_default();
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
