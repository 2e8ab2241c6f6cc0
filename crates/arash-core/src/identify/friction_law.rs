//! Each joint's Coulomb law chosen from the data: how its dry friction rises through zero speed.
//!
//! `sign(q̇)` says the friction is at its full value at any speed. Real joints rarely do that: a
//! harmonic drive's or a cable's friction rises over a speed of its own, and a joint that only
//! ever moves slowly through a reversal shows that rise in its torque. Fitted with `sign(q̇)`,
//! that shortfall near zero speed is left in the residual, where it reads as a Stribeck term of
//! the wrong sign (less friction near zero, not more), as hysteresis or as a cable's compliance
//! (issue 44: most joints of three real robots). So each joint's law is `tanh(q̇/v)` with its
//! *friction velocity* v, or `sign(q̇)` (v → 0), chosen by the fit: the law whose Coulomb column
//! leaves the least weighted squared error, the other columns refitted. One nonlinear parameter
//! per joint, searched over a grid of [`FRICTION_VELOCITY_SHARES`] of the joint's RMS speed,
//! one joint at a time ([`LAW_SWEEPS`] passes over the joints).
//!
//! Identification and the diagnosis both call [`choose_laws`] when the robot declares no law
//! ([`crate::model::CoulombLaws::is_declared`]); the model file keeps the result, and the
//! controllers' friction compensation and the diagnosis against that file use it.

use super::estimate::{coulomb_positions, regressor_rows};
use super::preprocess::{PreprocessError, Preprocessed};
use crate::base_parameters::BaseParameters;
use crate::effects::FRICTION_VELOCITY_SHARES;
use crate::model::{CoulombLaws, CoulombShape, Model};
use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

/// A smooth law replaces `sign(q̇)` only where its fit is better beyond chance: an F-test of the
/// cut in the joint's squared error at this level, shared over the grid's velocities
/// (Bonferroni), as the diagnosis tests its effects (`DiagnoseOptions::alpha`'s default). At a
/// cut-off far below the friction's transition every law filters to nearly the same column, and
/// the best of eleven would otherwise be chosen by the noise.
pub const LAW_ALPHA: f64 = 0.01;

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
    /// The independent samples each joint's residual holds (a residual filtered at c over T
    /// seconds holds about 2cT): the F-test's degrees of freedom.
    pub independent: f64,
}

/// The laws chosen, and what chose them.
#[derive(Clone, Debug)]
pub struct ChosenLaws {
    pub laws: CoulombLaws,
    /// Per joint with a Coulomb column: each candidate's law and the fit's weighted squared
    /// error over the error with `sign(q̇)`, at the last pass.
    pub scores: Vec<(usize, Vec<(CoulombShape, f64)>)>,
    pub reason: String,
}

/// The candidate laws of a joint whose RMS speed (filtered, as the friction velocity is) is
/// `rms_speed`: `sign(q̇)`, then `tanh(q̇/v)` for every share.
pub fn candidate_laws(rms_speed: f64) -> Vec<CoulombShape> {
    let smooth = FRICTION_VELOCITY_SHARES.iter().filter_map(|s| CoulombShape::tanh(s * rms_speed));
    std::iter::once(CoulombShape::Sign).chain(smooth).collect()
}

/// Each joint's law: the candidate ([`candidate_laws`] of `rms_speed[k]`) whose Coulomb column
/// fits best with every other column refitted. `column(k, law)` gives joint `k`'s Coulomb
/// column under `law` at the problem's samples, unweighted, as the fit filters it; `start` are
/// the laws the problem's columns hold. Joints without a Coulomb column keep theirs.
pub fn choose_laws(
    mut problem: LawProblem,
    rms_speed: &[f64],
    start: &CoulombLaws,
    column: impl Fn(usize, CoulombShape) -> Vec<f64>,
) -> ChosenLaws {
    let mut shapes: Vec<CoulombShape> = start.shapes().to_vec();
    // Each Coulomb joint's candidate laws with their weighted columns.
    let candidates: Vec<Vec<Candidate>> = problem
        .coulomb
        .iter()
        .map(|&(k, _)| {
            let laws = candidate_laws(rms_speed[k]);
            laws.into_iter().map(|law| (law, weighted(column(k, law), problem.weights[k]))).collect()
        })
        .collect();
    let mut gram = Gram::of(&problem);
    let mut scores = Vec::new();
    for sweep in 0..LAW_SWEEPS {
        let coulomb = problem.coulomb.clone();
        for (&(k, c), laws) in coulomb.iter().zip(&candidates) {
            let Some(others) = gram.without(c) else { continue };
            let errors: Vec<f64> = laws.iter().map(|(_, v)| others.error_with(&problem, (k, v))).collect();
            let on_grid =
                (0..laws.len()).min_by(|&a, &b| errors[a].total_cmp(&errors[b])).expect("sign is a candidate");
            // Between the grid's neighbours of the best smooth law, to a fraction of a per cent.
            let (fittest_law, fittest_column, fittest_error) = match on_grid {
                0 => (laws[0].0, laws[0].1.clone(), errors[0]),
                i => {
                    let around = (laws[(i - 1).max(1)].0, laws[(i + 1).min(laws.len() - 1)].0);
                    let error_at = |law: CoulombShape| {
                        let values = weighted(column(k, law), problem.weights[k]);
                        (others.error_with(&problem, (k, &values)), values)
                    };
                    refine(around, (laws[i].0, errors[i]), error_at)
                }
            };
            put(&mut problem, (c, k), &fittest_column);
            gram.replace(&problem, c);
            // F = (sign − fittest) / (e_k / n), e_k the joint's residual with the fittest law and n
            // its independent samples, against F(1, n) at LAW_ALPHA over the smooth candidates.
            let n = problem.independent.max(2.0);
            let residual = gram.joint_error(&problem, k);
            let threshold = FisherSnedecor::new(1.0, n)
                .map_or(f64::INFINITY, |f| f.inverse_cdf(1.0 - LAW_ALPHA / (laws.len() - 1).max(1) as f64));
            let beyond_chance = residual.is_some_and(|e| e > 0.0 && (errors[0] - fittest_error) / (e / n) > threshold);
            shapes[k] = match beyond_chance {
                true => fittest_law,
                false => {
                    put(&mut problem, (c, k), &laws[0].1);
                    gram.replace(&problem, c);
                    laws[0].0
                }
            };
            if sweep + 1 == LAW_SWEEPS {
                let sign = errors[0].max(f64::MIN_POSITIVE);
                let mut score: Vec<(CoulombShape, f64)> =
                    laws.iter().zip(&errors).map(|((law, _), e)| (*law, e / sign)).collect();
                score.push((fittest_law, fittest_error / sign));
                scores.push((k, score));
            }
        }
    }
    let laws = CoulombLaws::declared(shapes);
    let reason = explain(&laws, &scores, rms_speed);
    ChosenLaws { laws, scores, reason }
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

/// At most this many samples are fitted per candidate law: evenly spread over a long log, they
/// choose as all of it would, at a bounded cost.
const MOST_FITTED: usize = 10_000;

/// Identification's laws: [`choose_laws`] on the preprocessed log's settled samples (at most
/// [`MOST_FITTED`] of them), each joint's rows weighted by one over its filtered torque's RMS so
/// that N·m and N do not mix. The non-Coulomb columns are taken unfiltered here (they are smooth;
/// the fit itself filters them) and the Coulomb candidates filtered like the torque, as the fit
/// builds them. `None` when the declared model has no Coulomb column.
pub fn laws_for_fit(
    model: &Model,
    base: &BaseParameters,
    data: &Preprocessed,
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
    let column = |k: usize, law: CoulombShape| -> Result<Vec<f64>, PreprocessError> {
        let filtered = data.filter_like_torque(&data.friction.joint_directions(k, dof, law), 1)?;
        Ok(rows.iter().map(|&s| filtered[s]).collect())
    };
    let mut stacked: Vec<Vec<f64>> =
        (0..w.ncols()).map(|c| (0..w.nrows()).map(|r| w[(r, c)] * weights[r % dof]).collect()).collect();
    for &(k, c) in &positions {
        for (s, v) in column(k, model.coulomb_laws.shape(k))?.iter().enumerate() {
            stacked[c][s * dof + k] = v * weights[k];
        }
    }
    // Every grid candidate is filtered once, up front, so that a filter that cannot be built fails
    // here; the refinement's columns have the same length and filter alike.
    let mut cache = std::collections::HashMap::new();
    for &(k, _) in &positions {
        for law in candidate_laws(rms_speed[k]) {
            cache.insert((k, law.epsilon().map(f64::to_bits)), column(k, law)?);
        }
    }
    let y = rows
        .iter()
        .flat_map(|&s| (0..dof).map(move |k| (s, k)))
        .map(|(s, k)| data.tau[s * dof + k] * weights[k])
        .collect();
    // A residual filtered at the cut-off holds about two independent samples per cut-off period.
    let independent = (2.0 * data.cutoff_hz * data.settled.len() as f64 / data.rate_hz()).min(rows.len() as f64);
    let problem = LawProblem { columns: stacked, y, dof, coulomb: positions, weights, independent };
    let chosen = choose_laws(problem, &rms_speed, &model.coulomb_laws, |k, law| {
        match cache.get(&(k, law.epsilon().map(f64::to_bits))) {
            Some(values) => values.clone(),
            None => column(k, law).expect("a column of the same length filtered before"),
        }
    });
    Ok(Some(chosen))
}

/// A candidate law and its column on its joint's rows, weighted.
type Candidate = (CoulombShape, Vec<f64>);

/// Golden-section steps that refine a friction velocity between its grid neighbours: the bracket,
/// a factor of about 4.8, shrinks to within 0.3 % of the best.
const REFINE_STEPS: usize = 14;

/// The law of least error between the two laws of `around` (both smooth), starting from `best`
/// (its law and error): a golden-section search in log v, `error_at(law)` giving a law's error
/// and its column. Returns the law, its column and its error.
fn refine(
    around: (CoulombShape, CoulombShape),
    best: (CoulombShape, f64),
    error_at: impl Fn(CoulombShape) -> (f64, Vec<f64>),
) -> (CoulombShape, Vec<f64>, f64) {
    let log_v = |law: CoulombShape| law.epsilon().map_or(f64::NEG_INFINITY, f64::ln);
    let law_at = |x: f64| CoulombShape::Tanh { epsilon: x.exp() };
    let (mut a, mut b) = (log_v(around.0), log_v(around.1));
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (b - ratio * (b - a), a + ratio * (b - a));
    let (mut f1, mut f2) = (error_at(law_at(x1)), error_at(law_at(x2)));
    for _ in 0..REFINE_STEPS {
        if f1.0 <= f2.0 {
            (b, x2, f2) = (x2, x1, f1);
            x1 = b - ratio * (b - a);
            f1 = error_at(law_at(x1));
        } else {
            (a, x1, f1) = (x1, x2, f2);
            x2 = a + ratio * (b - a);
            f2 = error_at(law_at(x2));
        }
    }
    let (x, (error, column)) = if f1.0 <= f2.0 { (x1, f1) } else { (x2, f2) };
    match error <= best.1 {
        true => (law_at(x), column, error),
        false => (best.0, error_at(best.0).1, best.1),
    }
}

/// Joint `k`'s rows of column `c` set to `values`.
fn put(problem: &mut LawProblem, (c, k): (usize, usize), values: &[f64]) {
    for (s, v) in values.iter().enumerate() {
        problem.columns[c][s * problem.dof + k] = *v;
    }
}

/// `values` (one joint's rows) times its row weight.
fn weighted(mut values: Vec<f64>, weight: f64) -> Vec<f64> {
    values.iter_mut().for_each(|v| *v *= weight);
    values
}

/// One line for the reasons: each joint's law, its friction velocity against its RMS speed, and
/// how much better it fits than `sign(q̇)`.
fn explain(laws: &CoulombLaws, scores: &[(usize, Vec<(CoulombShape, f64)>)], rms_speed: &[f64]) -> String {
    let joints: Vec<String> = scores
        .iter()
        .map(|(k, errors)| {
            let law = laws.shape(*k);
            let error = errors.iter().find(|(l, _)| *l == law).map_or(1.0, |(_, e)| *e);
            match law.epsilon() {
                None => format!("joint {k} sign(q̇)"),
                Some(v) => format!(
                    "joint {k} tanh(q̇/{v:.3e}) ({:.3} × its RMS speed; squared error {:.1} % of sign(q̇)'s)",
                    v / rms_speed[*k],
                    100.0 * error
                ),
            }
        })
        .collect();
    format!(
        "Coulomb laws chosen from the data, each joint's the best fit of tanh(q̇/v) for v from {} to {} × its RMS \
         speed where it fits better than sign(q̇) beyond chance (F-test at {LAW_ALPHA} over the velocities), else \
         sign(q̇): {}",
        FRICTION_VELOCITY_SHARES[0],
        FRICTION_VELOCITY_SHARES[FRICTION_VELOCITY_SHARES.len() - 1],
        joints.join("; ")
    )
}

/// The Gram matrix `XᵀX` of the problem's columns and `Xᵀy`, kept up to date as columns change.
struct Gram {
    g: DMatrix<f64>,
    b: DVector<f64>,
    yy: f64,
}

/// The fit of every column but one: what a candidate column is judged against.
struct Others {
    /// The indices of the other columns, in order.
    kept: Vec<usize>,
    /// Cholesky factor of their Gram matrix (scaled to unit diagonal by `scale`).
    chol: nalgebra::Cholesky<f64, nalgebra::Dyn>,
    scale: Vec<f64>,
    /// Their coefficients fitted to y, and the residual's squared norm.
    beta: DVector<f64>,
    error: f64,
}

impl Gram {
    fn of(problem: &LawProblem) -> Self {
        let p = problem.columns.len();
        let mut g = DMatrix::zeros(p, p);
        let mut b = DVector::zeros(p);
        for i in 0..p {
            for j in i..p {
                let v = dot(&problem.columns[i], &problem.columns[j]);
                g[(i, j)] = v;
                g[(j, i)] = v;
            }
            b[i] = dot(&problem.columns[i], &problem.y);
        }
        Self { g, b, yy: dot(&problem.y, &problem.y) }
    }

    /// Column `c` changed: its row and column of the Gram matrix, and its entry of `Xᵀy`.
    fn replace(&mut self, problem: &LawProblem, c: usize) {
        for i in 0..problem.columns.len() {
            let v = dot(&problem.columns[i], &problem.columns[c]);
            self.g[(i, c)] = v;
            self.g[(c, i)] = v;
        }
        self.b[c] = dot(&problem.columns[c], &problem.y);
    }

    /// Joint `k`'s residual sum of squares of the fit on every column; `None` when they are
    /// dependent.
    fn joint_error(&self, problem: &LawProblem, k: usize) -> Option<f64> {
        let all = self.without(usize::MAX)?;
        let dof = problem.dof;
        let samples = problem.y.len() / dof;
        let fitted = |r: usize| -> f64 {
            all.kept.iter().enumerate().map(|(i, &c)| problem.columns[c][r] * all.beta[i] / all.scale[i]).sum()
        };
        Some((0..samples).map(|s| s * dof + k).map(|r| (problem.y[r] - fitted(r)).powi(2)).sum())
    }

    /// The fit without column `c` (every column for an index beyond them); `None` when the
    /// others are dependent.
    fn without(&self, c: usize) -> Option<Others> {
        let kept: Vec<usize> = (0..self.g.nrows()).filter(|&i| i != c && self.g[(i, i)] > 0.0).collect();
        let scale: Vec<f64> = kept.iter().map(|&i| self.g[(i, i)].sqrt()).collect();
        let p = kept.len();
        let g = DMatrix::from_fn(p, p, |i, j| self.g[(kept[i], kept[j])] / (scale[i] * scale[j]));
        let chol = g.cholesky()?;
        let b = DVector::from_fn(p, |i, _| self.b[kept[i]] / scale[i]);
        let beta = chol.solve(&b);
        let error = (self.yy - b.dot(&beta)).max(0.0);
        Some(Others { kept, chol, scale, beta, error })
    }
}

impl Others {
    /// The weighted squared error of the fit with joint `k`'s column `values` added.
    fn error_with(&self, problem: &LawProblem, (k, values): (usize, &[f64])) -> f64 {
        let dof = problem.dof;
        let on_joint = |x: &[f64]| values.iter().enumerate().map(|(s, v)| v * x[s * dof + k]).sum::<f64>();
        let xc = DVector::from_fn(self.kept.len(), |i, _| on_joint(&problem.columns[self.kept[i]]) / self.scale[i]);
        let cc = dot(values, values);
        let cy = on_joint(&problem.y);
        // The column's part outside the others' span, and its product with their residual.
        let outside = cc - xc.dot(&self.chol.solve(&xc));
        let along = cy - xc.dot(&self.beta);
        if outside <= 1e-12 * cc {
            return self.error;
        }
        (self.error - along * along / outside).max(0.0)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let column = |_: usize, law: CoulombShape| velocity.iter().map(|v| law.eval(*v)).collect::<Vec<f64>>();
            let problem = LawProblem {
                columns: vec![velocity.clone(), column(0, CoulombShape::Sign)],
                y,
                dof: 1,
                coulomb: vec![(0, 1)],
                weights: vec![1.0],
                independent: n as f64,
            };
            let chosen = choose_laws(problem, &[rms], &CoulombLaws::undeclared(1), column);
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

    /// The error the Gram update gives a candidate is the error of fitting it directly.
    #[test]
    fn the_error_with_a_candidate_is_the_direct_fit_error() {
        let n = 300;
        let a: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.1).sin()).collect();
        let b: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.023).cos()).collect();
        let y: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.05).sin() + 0.1 * (i % 7) as f64).collect();
        let candidate: Vec<f64> = (0..n).map(|s| ((s as f64) * 0.031).tanh()).collect();
        let problem = LawProblem {
            columns: vec![a.clone(), b.clone()],
            y: y.clone(),
            dof: 2,
            coulomb: vec![],
            weights: vec![1.0; 2],
            independent: 0.0,
        };
        let others = Gram::of(&problem).without(usize::MAX).unwrap();
        let got = others.error_with(&problem, (1, &candidate));
        // Direct: least squares on [a, b, c] with c on joint 1's rows.
        let mut c = vec![0.0; 2 * n];
        for s in 0..n {
            c[2 * s + 1] = candidate[s];
        }
        let x = DMatrix::from_fn(2 * n, 3, |r, j| [&a, &b, &c][j][r]);
        let beta = (x.transpose() * &x).cholesky().unwrap().solve(&(x.transpose() * DVector::from_vec(y.clone())));
        let e = DVector::from_vec(y) - x * beta;
        assert!((got / e.norm_squared() - 1.0).abs() < 1e-9, "{got} against {}", e.norm_squared());
    }
}
