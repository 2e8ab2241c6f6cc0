//! The weighted regression a diagnosis solves on one log, its held-out split, and the errors it
//! reports.

use super::findings::ErrorSummary;
use super::noise::NoiseFloor;
use super::prepare::Prepared;
use super::regression::{least_squares, residual, Column, NormalEquations, Rows};
use crate::effects::EffectTerm;
use crate::model_file::Metrics;
use crate::signal::estimate::joint_metrics;

/// The fewest blocks of the held-out split. A log shorter than this many `block_s` gets this many
/// shorter blocks, so that the even blocks and the odd ones both cover the motion: fitted on
/// two 2 s blocks of a 9 s log, a position-dependent term extrapolates over the range the odd
/// ones reach, and a true effect cut their error by −60 % to −8000 %.
pub(super) const MIN_HELDOUT_BLOCKS: usize = 10;

/// A held-out block spans at least this many of the filter's memories, so that the guards at its
/// two ends (one memory each) leave at least half of it to fit or judge.
pub(super) const BLOCK_MEMORIES: f64 = 4.0;

/// The held-out split of a log's kept samples (full-rate indices `kept` at `fs`): blocks of time,
/// fit on the even ones and judge on the odd ones.
///
/// Filtering spreads each sample's noise over the filter's memory (`memory_s`), so a fitted
/// sample and a judged one closer than twice that share noise, and the fit would be rewarded on
/// the held-out block for fitting it. Each side therefore leaves out the samples within one memory
/// of every boundary between an even and an odd block.
#[derive(Clone, Debug)]
pub(super) struct Split {
    /// The number of blocks.
    pub(super) count: usize,
    /// The blocks' length (s).
    pub(super) block_s: f64,
    /// The samples fitted (even blocks) and judged (odd blocks), guards left out of both.
    pub(super) train: Vec<bool>,
    pub(super) test: Vec<bool>,
}

/// The held-out split of `kept`: blocks of `longest_s`, or of a tenth of a log shorter than
/// [`MIN_HELDOUT_BLOCKS`] of them, never shorter than [`BLOCK_MEMORIES`] filter memories; the last
/// partial block joins the one before it.
pub(super) fn heldout_split(kept: &[usize], fs: f64, longest_s: f64, memory_s: f64) -> Split {
    let stride = kept.get(1).map_or(1, |k| k - kept[0]);
    let span = (kept.last().unwrap_or(&0) - kept.first().unwrap_or(&0) + stride) as f64 / fs;
    let block_s = longest_s.min(span / MIN_HELDOUT_BLOCKS as f64).max(BLOCK_MEMORIES * memory_s);
    let per = (block_s * fs).max(1.0);
    let first = kept.first().copied().unwrap_or(0);
    let raw: Vec<usize> = kept.iter().map(|&i| ((i - first) as f64 / per) as usize).collect();
    let last = *raw.last().unwrap_or(&0);
    let count_last = raw.iter().filter(|&&b| b == last).count();
    let merge = last > 0 && (count_last as f64) < 0.5 * per / stride as f64;
    let block: Vec<usize> = raw.iter().map(|&b| if merge && b == last { last - 1 } else { b }).collect();
    let count = block.last().map_or(0, |b| b + 1);
    // Distance (samples) to the nearest boundary between two blocks.
    let guard = memory_s * fs;
    let boundaries: Vec<f64> = (1..count).map(|b| b as f64 * per).collect();
    let clear = |i: usize| boundaries.iter().all(|b| ((i - first) as f64 - b).abs() >= guard);
    let train = block.iter().zip(kept).map(|(b, &i)| b % 2 == 0 && clear(i)).collect();
    let test = block.iter().zip(kept).map(|(b, &i)| b % 2 == 1 && clear(i)).collect();
    Split { count, block_s, train, test }
}

/// The weighted problem on one log: the target `y = w·(τ − τ_given)` and every column scaled by
/// the joint weights `w`.
pub(super) struct Problem {
    pub(super) dof: usize,
    pub(super) weights: Vec<f64>,
    pub(super) tau: Vec<f64>,
    pub(super) y: Vec<f64>,
    pub(super) declared: Vec<Column>,
    /// Which declared columns are fitted (the others are held at the given model's values).
    pub(super) free: Vec<bool>,
}

impl Problem {
    pub(super) fn new(data: &Prepared, tau: Vec<f64>, fixed: Vec<f64>, weights: &[f64], free: &[bool]) -> Self {
        let dof = data.dof;
        let y = tau.iter().zip(&fixed).enumerate().map(|(i, (t, f))| (t - f) * weights[i % dof]).collect();
        let declared = data
            .declared
            .iter()
            .map(|c| {
                let mut c = c.clone();
                c.scale_rows(weights);
                c
            })
            .collect();
        Self { dof, weights: weights.to_vec(), tau, y, declared, free: free.to_vec() }
    }

    pub(super) fn weighted(&self, mut columns: Vec<Column>) -> Vec<Column> {
        columns.iter_mut().for_each(|c| c.scale_rows(&self.weights));
        columns
    }

    /// The declared columns that are fitted.
    pub(super) fn free_columns(&self) -> impl Iterator<Item = &Column> {
        self.declared.iter().zip(&self.free).filter(|(_, f)| **f).map(|(c, _)| c)
    }

    /// Unweighted per-joint metrics of the fit `coefficients` on `columns` over `rows`.
    pub(super) fn metrics(&self, columns: &[&Column], coefficients: &[f64], rows: Rows) -> Metrics {
        self.metrics_of(&residual(columns, coefficients, &self.y, self.dof), rows)
    }

    /// Unweighted per-joint metrics of a weighted residual `e` on every row, over `rows`.
    pub(super) fn metrics_of(&self, e: &[f64], rows: Rows) -> Metrics {
        let (mut tau, mut pred) = (Vec::new(), Vec::new());
        for s in 0..self.tau.len() / self.dof {
            if let Rows::Where(m) = rows {
                if !m[s] {
                    continue;
                }
            }
            for k in 0..self.dof {
                let i = s * self.dof + k;
                tau.push(self.tau[i]);
                pred.push(self.tau[i] - e[i] / self.weights[k]);
            }
        }
        joint_metrics(&tau, &pred, self.dof).into()
    }

    /// Unweighted residual of a fit, on every row.
    pub(super) fn residual(&self, columns: &[&Column], coefficients: &[f64]) -> Vec<f64> {
        let e = residual(columns, coefficients, &self.y, self.dof);
        e.iter().enumerate().map(|(i, e)| e / self.weights[i % self.dof]).collect()
    }
}

/// Where held-out errors are measured: a validation log, or the odd blocks of the training log
/// while fitting on the even ones.
pub(super) enum HeldOut {
    Validation(Problem),
    Blocks { train: Vec<bool>, test: Vec<bool> },
}

impl HeldOut {
    /// How many samples the held-out error is measured on.
    pub(super) fn samples(&self, dof: usize) -> usize {
        match self {
            HeldOut::Validation(v) => v.y.len() / dof,
            HeldOut::Blocks { test, .. } => test.iter().filter(|t| **t).count(),
        }
    }
}

/// A candidate in the search: its term and its weighted columns on each log.
pub(super) struct Candidate {
    pub(super) term: EffectTerm,
    pub(super) columns: Vec<Column>,
    pub(super) validation: Vec<Column>,
}

/// The model's columns: the declared ones that are fitted, then the chosen effects'.
pub(super) fn model_columns<'a>(problem: &'a Problem, pool: &'a [Candidate], chosen: &[usize]) -> Vec<&'a Column> {
    problem.free_columns().chain(chosen.iter().flat_map(|&i| pool[i].columns.iter())).collect()
}

/// The same columns on the validation log.
pub(super) fn validation_columns<'a>(
    validation: &'a Problem,
    pool: &'a [Candidate],
    chosen: &[usize],
) -> Vec<&'a Column> {
    validation.free_columns().chain(chosen.iter().flat_map(|&i| pool[i].validation.iter())).collect()
}

/// Weighted squared error per joint of `y − X x` over `rows`.
pub(super) fn sse(columns: &[&Column], x: &[f64], y: &[f64], dof: usize, rows: Rows) -> Vec<f64> {
    let e = residual(columns, x, y, dof);
    let mut out = vec![0.0; dof];
    for (i, v) in e.iter().enumerate() {
        if let Rows::Where(m) = rows {
            if !m[i / dof] {
                continue;
            }
        }
        out[i % dof] += v * v;
    }
    out
}

/// Held-out residual (weighted, held-out samples only, sample by sample) of the model with the
/// free declared columns and the effects `chosen`, fitted on the training rows.
pub(super) fn heldout_residual(problem: &Problem, heldout: &HeldOut, pool: &[Candidate], chosen: &[usize]) -> Vec<f64> {
    let dof = problem.dof;
    let cols = model_columns(problem, pool, chosen);
    match heldout {
        HeldOut::Blocks { train, test } => {
            let x = least_squares(&cols, &problem.y, dof, Rows::Where(train)).unwrap_or_else(|| vec![0.0; cols.len()]);
            on_rows(&residual(&cols, &x, &problem.y, dof), test, dof)
        }
        HeldOut::Validation(v) => {
            let x = least_squares(&cols, &problem.y, dof, Rows::All).unwrap_or_else(|| vec![0.0; cols.len()]);
            residual(&validation_columns(v, pool, chosen), &x, &v.y, dof)
        }
    }
}

/// The rows of the samples marked in `mask`, sample by sample.
pub(super) fn on_rows(e: &[f64], mask: &[bool], dof: usize) -> Vec<f64> {
    e.chunks(dof).zip(mask).filter(|(_, m)| **m).flat_map(|(row, _)| row.iter().copied()).collect()
}

/// Held-out squared error per joint of the model `chosen`, fitted on the training rows.
pub(super) fn heldout_sse(problem: &Problem, heldout: &HeldOut, pool: &[Candidate], chosen: &[usize]) -> Vec<f64> {
    let dof = problem.dof;
    let mut out = vec![0.0; dof];
    for (i, e) in heldout_residual(problem, heldout, pool, chosen).iter().enumerate() {
        out[i % dof] += e * e;
    }
    out
}

/// The current model's fit on the rows it is trained on for held-out scoring, computed once per
/// round so that each candidate costs only its own products with the model.
pub(super) struct HeldOutBase<'a> {
    problem: &'a Problem,
    heldout: &'a HeldOut,
    pool: &'a [Candidate],
    chosen: Vec<usize>,
    training: NormalEquations<'a>,
    sse: Vec<f64>,
}

impl<'a> HeldOutBase<'a> {
    pub(super) fn new(problem: &'a Problem, heldout: &'a HeldOut, pool: &'a [Candidate], chosen: &[usize]) -> Self {
        let rows = match heldout {
            HeldOut::Blocks { train, .. } => Rows::Where(train),
            HeldOut::Validation(_) => Rows::All,
        };
        let training = NormalEquations::over(model_columns(problem, pool, chosen), &problem.y, problem.dof, rows);
        let sse = heldout_sse(problem, heldout, pool, chosen);
        Self { problem, heldout, pool, chosen: chosen.to_vec(), training, sse }
    }

    /// Relative cut of the held-out squared error from adding candidate `i`: per joint, of the
    /// error above the noise `floor` ([`NoiseFloor::gains`]), and over all joints together (in
    /// the weighted units, where every joint counts by its noise).
    pub(super) fn gain(&self, floor: &NoiseFloor, i: usize) -> (Vec<f64>, f64) {
        self.gain_of(floor, &self.pool[i])
    }

    /// [`Self::gain`] of a candidate outside the pool (a pool's term at another scale).
    pub(super) fn gain_of(&self, floor: &NoiseFloor, candidate: &Candidate) -> (Vec<f64>, f64) {
        let (problem, heldout, pool, chosen) = (self.problem, self.heldout, self.pool, &self.chosen[..]);
        let dof = problem.dof;
        let group: Vec<&Column> = candidate.columns.iter().collect();
        let after = match self.training.with_group(&group, &problem.y) {
            None => self.sse.clone(),
            Some(x) => match heldout {
                HeldOut::Blocks { test, .. } => {
                    let all: Vec<&Column> =
                        self.training.columns.iter().copied().chain(group.iter().copied()).collect();
                    sse(&all, &x, &problem.y, dof, Rows::Where(test))
                }
                HeldOut::Validation(v) => {
                    let all: Vec<&Column> =
                        validation_columns(v, pool, chosen).into_iter().chain(candidate.validation.iter()).collect();
                    sse(&all, &x, &v.y, dof, Rows::All)
                }
            },
        };
        let before = &self.sse;
        let per_joint = floor.gains(before, &after);
        let total = 1.0 - after.iter().sum::<f64>() / before.iter().sum::<f64>().max(f64::MIN_POSITIVE);
        (per_joint, total)
    }
}

pub(super) fn error_summary(
    problem: &Problem,
    heldout: &HeldOut,
    pool: &[Candidate],
    chosen: &[usize],
) -> ErrorSummary {
    let dof = problem.dof;
    let cols = model_columns(problem, pool, chosen);
    let x_all = least_squares(&cols, &problem.y, dof, Rows::All).unwrap_or_else(|| vec![0.0; cols.len()]);
    let training = problem.metrics(&cols, &x_all, Rows::All);
    let heldout = match heldout {
        HeldOut::Blocks { train, test } => {
            let x = least_squares(&cols, &problem.y, dof, Rows::Where(train)).unwrap_or_else(|| vec![0.0; cols.len()]);
            problem.metrics(&cols, &x, Rows::Where(test))
        }
        HeldOut::Validation(v) => v.metrics(&validation_columns(v, pool, chosen), &x_all, Rows::All),
    };
    ErrorSummary { training, heldout }
}
