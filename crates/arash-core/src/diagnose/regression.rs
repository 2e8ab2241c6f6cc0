//! The regression machinery of the diagnosis: stacked columns that are either dense over every
//! joint's rows or live on one joint's rows only, least squares through column-scaled Gram
//! matrices, and the block Wald test of a column group added to a fitted model.
//!
//! Rows are ordered sample by sample, joint by joint, as in [`crate::signal::estimate`]. A
//! candidate effect usually acts on one joint, so storing only that joint's rows saves `dof`-fold
//! memory and time on every product with it.

use faer::{Mat, Scale};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::dense::{self, Unseen};

/// One regressor column.
#[derive(Clone, Debug)]
pub enum Column {
    /// Values on every row: `rows` interleaved (`samples × dof`), and the same joint by joint
    /// (`planes[k·samples + s]`), so that a product with a one-joint column reads memory
    /// contiguously.
    All { rows: Vec<f64>, planes: Vec<f64> },
    /// Values on joint `k`'s rows only (`samples`); zero elsewhere.
    Joint(usize, Vec<f64>),
}

impl Column {
    /// A column with values on every row (`samples × dof`, interleaved).
    pub fn dense(rows: Vec<f64>, dof: usize) -> Self {
        let n = rows.len() / dof;
        let mut planes = vec![0.0; rows.len()];
        for (i, v) in rows.iter().enumerate() {
            planes[(i % dof) * n + i / dof] = *v;
        }
        Column::All { rows, planes }
    }

    /// The value on row `sample·dof + joint`.
    #[inline]
    pub fn at(&self, sample: usize, joint: usize, dof: usize) -> f64 {
        match self {
            Column::All { rows, .. } => rows[sample * dof + joint],
            Column::Joint(k, v) if *k == joint => v[sample],
            Column::Joint(..) => 0.0,
        }
    }

    /// Multiply joint `k`'s rows by `w[k]`.
    pub fn scale_rows(&mut self, w: &[f64]) {
        let dof = w.len();
        match self {
            Column::All { rows, planes } => {
                rows.iter_mut().enumerate().for_each(|(i, x)| *x *= w[i % dof]);
                let n = planes.len() / dof;
                planes.iter_mut().enumerate().for_each(|(i, x)| *x *= w[i / n]);
            }
            Column::Joint(k, v) => v.iter_mut().for_each(|x| *x *= w[*k]),
        }
    }
}

/// Which samples a sum runs over.
#[derive(Clone, Copy)]
pub enum Rows<'a> {
    All,
    /// Samples whose flag is `true`.
    Where(&'a [bool]),
}

impl Rows<'_> {
    #[inline]
    fn take(&self, s: usize) -> bool {
        match self {
            Rows::All => true,
            Rows::Where(m) => m[s],
        }
    }
}

/// `Σ a_i b_i` over the rows of the selected samples.
pub fn dot(a: &Column, b: &Column, dof: usize, rows: Rows) -> f64 {
    let masked = |x: &[f64], y: &[f64]| -> f64 {
        match rows {
            Rows::All => dense::dot(x, y),
            Rows::Where(m) => x.iter().zip(y).zip(m).filter(|(_, t)| **t).map(|((a, b), _)| a * b).sum(),
        }
    };
    match (a, b) {
        (Column::All { planes: x, .. }, Column::All { planes: y, .. }) => {
            let n = x.len() / dof;
            (0..dof).map(|k| masked(&x[k * n..(k + 1) * n], &y[k * n..(k + 1) * n])).sum()
        }
        (Column::Joint(k, x), Column::All { planes, .. }) | (Column::All { planes, .. }, Column::Joint(k, x)) => {
            let n = x.len();
            masked(x, &planes[k * n..(k + 1) * n])
        }
        (Column::Joint(k, x), Column::Joint(l, y)) if k == l => masked(x, y),
        (Column::Joint(..), Column::Joint(..)) => 0.0,
    }
}

/// `Σ a_i v_i` for a column and a dense row vector.
pub fn dot_dense(a: &Column, v: &[f64], dof: usize, rows: Rows) -> f64 {
    match (a, rows) {
        (Column::All { rows: x, .. }, Rows::All) => dense::dot(x, v),
        (Column::All { rows: x, .. }, Rows::Where(m)) => (0..v.len() / dof)
            .filter(|&s| m[s])
            .map(|s| (0..dof).map(|k| x[s * dof + k] * v[s * dof + k]).sum::<f64>())
            .sum(),
        (Column::Joint(k, x), rows) => (0..x.len()).filter(|&s| rows.take(s)).map(|s| x[s] * v[s * dof + k]).sum(),
    }
}

/// `v += c·a` on every row.
pub fn axpy(v: &mut [f64], c: f64, a: &Column, dof: usize) {
    match a {
        Column::All { rows, .. } => dense::axpy(v, c, rows),
        Column::Joint(k, x) => x.iter().enumerate().for_each(|(s, x)| v[s * dof + k] += c * x),
    }
}

/// Least squares of `y` on `columns` over `rows`: the coefficients, or `None` when the columns are
/// (numerically) dependent there. Solved on the Gram matrix with unit-diagonal scaling: the
/// diagnosis tests added columns, it does not need the last digits of the declared parameters
/// that [`crate::signal::estimate`] fights for.
pub fn least_squares(columns: &[&Column], y: &[f64], dof: usize, rows: Rows) -> Option<Vec<f64>> {
    if columns.is_empty() {
        return Some(vec![]);
    }
    solve_scaled(&gram(columns, dof, rows), &rhs(columns, y, dof, rows))
}

/// A model as fitted: its columns and their coefficients.
#[derive(Clone, Copy)]
pub struct Fitted<'a> {
    pub columns: &'a [&'a Column],
    pub coefficients: &'a [f64],
}

/// The normal equations of a model's columns over some rows: `XᵀX` and `Xᵀy`. Formed once per
/// model, they serve every group of columns tested or fitted alongside it, each of which then
/// costs only its own products.
pub struct NormalEquations<'a> {
    pub columns: Vec<&'a Column>,
    pub gram: Mat<f64>,
    pub rhs: Vec<f64>,
    pub rows: Rows<'a>,
    pub dof: usize,
}

impl<'a> NormalEquations<'a> {
    /// Of `columns` and the target `y` over `rows`.
    pub fn over(columns: Vec<&'a Column>, y: &[f64], dof: usize, rows: Rows<'a>) -> Self {
        let gram = gram(&columns, dof, rows);
        let rhs = rhs(&columns, y, dof, rows);
        Self { columns, gram, rhs, rows, dof }
    }

    /// The model's least-squares coefficients; `None` when its columns are dependent.
    pub fn solve(&self) -> Option<Vec<f64>> {
        solve_scaled(&self.gram, &self.rhs)
    }

    /// The least-squares coefficients of the same columns, over the same rows, for another
    /// target `y`: only `Xᵀy` is formed again.
    pub fn solve_for(&self, y: &[f64]) -> Option<Vec<f64>> {
        solve_scaled(&self.gram, &rhs(&self.columns, y, self.dof, self.rows))
    }

    /// Least squares of the same `y` on the model's columns plus `group`: coefficients of the
    /// model's columns, then of the group.
    pub fn with_group(&self, group: &[&Column], y: &[f64]) -> Option<Vec<f64>> {
        let (p, k, dof, rows) = (self.columns.len(), group.len(), self.dof, self.rows);
        let mut g = Mat::zeros(p + k, p + k);
        g.submatrix_mut(0, 0, p, p).copy_from(&self.gram);
        let mut b = self.rhs.clone();
        b.resize(p + k, 0.0);
        for (j, c) in group.iter().enumerate() {
            for (i, x) in self.columns.iter().enumerate() {
                let v = dot(x, c, dof, rows);
                g[(i, p + j)] = v;
                g[(p + j, i)] = v;
            }
            for (i, d) in group.iter().enumerate().skip(j) {
                let v = dot(c, d, dof, rows);
                g[(p + i, p + j)] = v;
                g[(p + j, p + i)] = v;
            }
            b[p + j] = dot_dense(c, y, dof, rows);
        }
        solve_scaled(&g, &b)
    }
}

/// `Xᵀy` over `rows`.
pub fn rhs(columns: &[&Column], y: &[f64], dof: usize, rows: Rows) -> Vec<f64> {
    columns.iter().map(|c| dot_dense(c, y, dof, rows)).collect()
}

/// `XᵀX` over `rows`.
pub fn gram(columns: &[&Column], dof: usize, rows: Rows) -> Mat<f64> {
    let p = columns.len();
    let mut g = Mat::zeros(p, p);
    for i in 0..p {
        for j in i..p {
            let v = dot(columns[i], columns[j], dof, rows);
            g[(i, j)] = v;
            g[(j, i)] = v;
        }
    }
    g
}

/// Solve `G x = b` for a Gram matrix, scaled to unit diagonal; `None` if singular. A column
/// that is exactly zero (a direction the data cannot see, such as a payload's first moment along
/// a joint axis) is pinned: its coefficient is zero.
pub fn solve_scaled(g: &Mat<f64>, b: &[f64]) -> Option<Vec<f64>> {
    dense::solve_gram(g.as_ref(), b, Unseen::Pinned)
}

/// The inverse of a Gram matrix on its non-zero columns; zero rows and columns stay zero.
fn pinned_inverse(g: &Mat<f64>) -> Option<Mat<f64>> {
    let p = g.nrows();
    let pinned: Vec<bool> = (0..p).map(|i| g[(i, i)] == 0.0).collect();
    let mut h = g.clone();
    for i in (0..p).filter(|&i| pinned[i]) {
        h[(i, i)] = 1.0;
    }
    let mut inv = dense::inverse(h.as_ref())?;
    for i in (0..p).filter(|&i| pinned[i]) {
        inv.row_mut(i).fill(0.0);
        inv.col_mut(i).fill(0.0);
    }
    Some(inv)
}

/// The residual `y − X c` on every row.
pub fn residual(columns: &[&Column], coefficients: &[f64], y: &[f64], dof: usize) -> Vec<f64> {
    let mut e = y.to_vec();
    for (c, x) in columns.iter().zip(coefficients) {
        axpy(&mut e, -x, c, dof);
    }
    e
}

/// What adding a column group to a fitted model gives.
#[derive(Clone, Debug)]
pub struct GroupTest {
    /// The group's coefficients in the joint fit.
    pub coefficients: Vec<f64>,
    /// Their standard deviations (batch sandwich).
    pub sigma: Vec<f64>,
    /// Hotelling-scaled Wald statistic, F(k, B − k) under "no effect".
    pub f_statistic: f64,
    pub p_value: f64,
    /// Smallest fraction of a column's norm that the fitted model does not explain (1/VIF).
    pub unexplained: f64,
    /// The batches the covariance was summed over (B), and their length in samples.
    pub batches: usize,
    pub batch_samples: usize,
}

/// How the samples of a test are cut into the batches its covariance is summed over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Batching {
    /// Each test chooses from its own scores by blocking (see [`test_group`]).
    FromScores,
    /// Batches of this many samples.
    Fixed(usize),
}

/// The fewest batches a test chosen from the scores may use: fewer leave the covariance so
/// uncertain that F(k, B − k) has no power at the thresholds Holm sets over many candidates.
pub const MIN_BATCHES: usize = 10;

/// Why a group could not be tested.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Untested {
    /// The group's columns are dependent on the model (or on each other).
    Dependent { unexplained: f64 },
    /// The log holds too few batches for `columns` coefficients: a covariance from `batches`
    /// batches cannot judge them.
    TooFewBatches { batches: usize, columns: usize },
}

/// Test `group` against the model `base` (already fitted, residual `e0`) by Frisch–Waugh–Lovell:
/// partial the model out of the group, regress the residual on what is left, and judge the
/// coefficients with a Wald test whose unit is a batch of consecutive samples.
///
/// Robot residuals are correlated in time (the filter's memory, and every unmodelled effect
/// repeats with the trajectory), so the covariance is the batch sandwich
/// `H⁻¹ (Σ_b g_b g_bᵀ) H⁻¹`, `g_b = C̃_bᵀ e_b`, and the statistic is scaled as Hotelling's T² to
/// `F(k, B − k)`, which stays honest with a few dozen batches. The batches are as long as the
/// scores' own correlation asks ([`Batching::FromScores`], by blocking: `plateau`): a fixed
/// length of seconds left a 9 s log four batches and no power, while a log whose residual is
/// correlated over seconds gets batches of seconds.
///
/// `known` are directions of an error in the target whose size is known rather than seen in
/// the batches (`Σ uᵢ uᵢᵀ`, a given model's calibration error: `diagnose/calibration_error.rs`);
/// their covariance `H⁻¹ C̃ᵀU UᵀC̃ H⁻¹` is added to the sandwich.
pub fn test_group(
    base: &NormalEquations,
    e0: &[f64],
    group: &[&Column],
    batching: Batching,
    known: &[Vec<f64>],
) -> Result<GroupTest, Untested> {
    let (k, dof) = (group.len(), base.dof);
    let dependent = Untested::Dependent { unexplained: 0.0 };
    let partialled = partial_out(base, group).ok_or(dependent)?;
    let unexplained = partialled
        .iter()
        .zip(group)
        .map(|(t, c)| {
            let own = dot(c, c, dof, Rows::All);
            if own > 0.0 {
                t.iter().map(|x| x * x).sum::<f64>() / own
            } else {
                f64::INFINITY // pinned (see `solve_scaled`), not dependent
            }
        })
        .fold(f64::INFINITY, f64::min);
    let h = Mat::from_fn(k, k, |i, j| dense::dot(&partialled[i], &partialled[j]));
    let rhs: Vec<f64> = partialled.iter().map(|c| dense::dot(c, e0)).collect();
    let gamma = solve_scaled(&h, &rhs).ok_or(Untested::Dependent { unexplained })?;
    let h_inv = pinned_inverse(&h).ok_or(Untested::Dependent { unexplained })?;
    let scores = sample_scores(&partialled, e0, &gamma, dof);
    let samples = scores.len() / k;
    let covariance = |length: usize| {
        let batches = samples / length;
        let meat = batch_meat(&scores, k, length, batches);
        (batches, &h_inv * &meat * &h_inv)
    };
    let wald = |cov: &Mat<f64>| solve_scaled(cov, &gamma).map_or(f64::INFINITY, |x| dense::dot(&gamma, &x));
    let length = match batching {
        Batching::Fixed(n) => n.max(1),
        Batching::FromScores => {
            let lengths: Vec<usize> =
                (0..).map(|j| 1 << j).take_while(|l| samples / l >= MIN_BATCHES.max(k + 2)).collect();
            // Each length's batch sums from the last one's, pairwise: one pass over the samples
            // for all the lengths, not one per length.
            let mut sums = BatchSums { values: scores.clone(), k, length: 1 };
            let walds: Vec<(usize, f64)> = lengths
                .iter()
                .map(|&l| {
                    while sums.length < l {
                        sums = sums.doubled(samples);
                    }
                    let batches = samples / l;
                    (batches, wald(&(&h_inv * &sums.meat() * &h_inv)))
                })
                .collect();
            // From the plateau on, the length with the largest variance: a plateau seen through
            // few long batches may still be rising.
            match plateau(&walds) {
                Some(i) => lengths[(i..walds.len()).min_by(|&a, &b| walds[a].1.total_cmp(&walds[b].1)).unwrap_or(i)],
                // With no length at all, batches of one sample each are already too few.
                None => {
                    let batches = walds.last().map_or(samples, |w| w.0);
                    return Err(Untested::TooFewBatches { batches, columns: k });
                }
            }
        }
    }
    .min(samples.max(1));
    let (batches, mut cov) = covariance(length);
    if !known.is_empty() {
        let m = Mat::from_fn(k, known.len(), |i, e| dense::dot(&partialled[i], &known[e]));
        cov += &h_inv * &m * m.transpose() * &h_inv;
    }
    if batches <= k + 1 {
        return Err(Untested::TooFewBatches { batches, columns: k });
    }
    let sigma: Vec<f64> = (0..k).map(|i| cov[(i, i)].max(0.0).sqrt()).collect();
    // A fitted coefficient the batches put no variance on (its scores vanish where its column
    // lives: a counterweight's mass beside its first moment on a 10 s ARASH:ASiST log gave
    // F = ∞ and "241.6 ± 0.0 g") is a direction the data do not see, not an infinite statistic.
    if gamma.iter().zip(&sigma).any(|(g, s)| *g != 0.0 && *s == 0.0) {
        return Err(Untested::Dependent { unexplained });
    }
    let wald = wald(&cov);
    let (df1, df2) = (k as f64, (batches - k) as f64);
    let f = wald * df2 / (df1 * (batches - 1) as f64);
    let p_value = FisherSnedecor::new(df1, df2).map_or(0.0, |d| d.sf(f));
    Ok(GroupTest { coefficients: gamma, sigma, f_statistic: f, p_value, unexplained, batches, batch_samples: length })
}

/// The joint fit's score of each sample, `c̃_sᵀ (e_s − C̃_s γ)` summed over the sample's joints:
/// `samples × k`, row-major.
fn sample_scores(partialled: &[Vec<f64>], e0: &[f64], gamma: &[f64], dof: usize) -> Vec<f64> {
    let k = partialled.len();
    let mut scores = vec![0.0; e0.len() / dof * k];
    for (i, e) in e0.iter().enumerate() {
        let fitted: f64 = (0..k).map(|j| partialled[j][i] * gamma[j]).sum();
        for j in 0..k {
            scores[(i / dof) * k + j] += partialled[j][i] * (e - fitted);
        }
    }
    scores
}

/// The scores summed over runs of `length` samples, `batches × k` row-major, the last partial run
/// joined to the one before it (as [`batch_meat`] sums them).
struct BatchSums {
    values: Vec<f64>,
    k: usize,
    length: usize,
}

impl BatchSums {
    /// The sums over `batches` runs of `length` samples, summed directly, a batch at a time.
    fn over(scores: &[f64], k: usize, length: usize, batches: usize) -> Self {
        let count = batches.max(1);
        let mut values = vec![0.0; count * k];
        for (run, rows) in scores.chunks(length.max(1) * k).enumerate() {
            let b = run.min(count - 1);
            let sum = &mut values[b * k..(b + 1) * k];
            for row in rows.chunks_exact(k) {
                sum.iter_mut().zip(row).for_each(|(s, v)| *s += v);
            }
        }
        Self { values, k, length }
    }

    /// The sums over runs twice as long, of a log of `samples`: each run is two of these, and the
    /// last also takes what is left over (the floor of half the count is the count at twice the
    /// length).
    fn doubled(&self, samples: usize) -> Self {
        let k = self.k;
        let count = (samples / (2 * self.length)).max(1);
        let mut values = vec![0.0; count * k];
        for (b, row) in self.values.chunks_exact(k).enumerate() {
            let to = (b / 2).min(count - 1);
            values[to * k..(to + 1) * k].iter_mut().zip(row).for_each(|(s, v)| *s += v);
        }
        Self { values, k, length: 2 * self.length }
    }

    /// `Σ_b g_b g_bᵀ · B/(B − 1)`.
    fn meat(&self) -> Mat<f64> {
        let batches = self.values.len() / self.k;
        let sums = Mat::from_fn(batches, self.k, |b, j| self.values[b * self.k + j]);
        sums.transpose() * &sums * Scale(batches as f64 / (batches.max(2) - 1) as f64)
    }
}

/// `Σ_b g_b g_bᵀ · B/(B − 1)` over `batches` runs of `length` samples; the last partial run
/// joins the one before it.
fn batch_meat(scores: &[f64], k: usize, length: usize, batches: usize) -> Mat<f64> {
    BatchSums::over(scores, k, length, batches).meat()
}

/// Blocking (Flyvbjerg and Petersen): the covariance from batches of 1, 2, 4, … samples grows
/// with the batch length until the batches are longer than the scores' correlation, and then
/// stays. Of `(batches, Wald statistic)` by doubling length, the index of the first length that
/// no longer one shows to be short: no longer batches give a variance (a Wald statistic
/// smaller by a factor) beyond twice their own relative standard error, √(2/(B − 1)). A
/// residual that mixes fast noise with a slow misfit, as a closed loop's does, is caught this
/// way where a window on the autocorrelation closes on the fast part and misses the slow one.
/// A plateau needs a longer length to confirm it, so the longest never qualifies: `None` when
/// every length with enough batches is still short, and the log cannot support the test.
fn plateau(walds: &[(usize, f64)]) -> Option<usize> {
    let settled = |i: usize| {
        walds[i + 1..].iter().all(|&(batches, w)| w * (1.0 + 2.0 * (2.0 / (batches - 1) as f64).sqrt()) >= walds[i].1)
    };
    (0..walds.len().saturating_sub(1)).find(|&i| settled(i))
}

/// The sum of squares of `e0` (the residual of `base`'s fit over its rows) that adding `group`
/// to the fit explains: `rᵀH⁻¹r`, with `H = CᵀC − (XᵀC)ᵀ(XᵀX)⁻¹XᵀC` the group's Gram matrix
/// once `base` is partialled out and `r = Cᵀe0` (the partialled columns' product with `e0` is
/// the columns' own, since `e0` is orthogonal to `base`). From `base`'s Gram matrix, without
/// forming the partialled columns: a one-joint column costs its own rows only. `None` where the
/// group lies in `base`'s span.
pub fn explained(base: &NormalEquations, e0: &[f64], group: &[&Column]) -> Option<f64> {
    let (dof, rows, k) = (base.dof, base.rows, group.len());
    let r: Vec<f64> = group.iter().map(|c| dot_dense(c, e0, dof, rows)).collect();
    let xc: Vec<Vec<f64>> = group.iter().map(|c| base.columns.iter().map(|x| dot(x, c, dof, rows)).collect()).collect();
    let through: Vec<Vec<f64>> = match base.columns.is_empty() {
        true => vec![vec![]; k],
        false => xc.iter().map(|v| solve_scaled(&base.gram, v)).collect::<Option<_>>()?,
    };
    let h = Mat::from_fn(k, k, |i, j| dot(group[i], group[j], dof, rows) - dense::dot(&xc[i], &through[j]));
    let gamma = solve_scaled(&h, &r)?;
    Some(r.iter().zip(&gamma).map(|(r, g)| r * g).sum())
}

/// `C − X (XᵀX)⁻¹ XᵀC` for each column of the group, dense over every row.
fn partial_out(base: &NormalEquations, group: &[&Column]) -> Option<Vec<Vec<f64>>> {
    let dof = base.dof;
    let rows = match group.first()? {
        Column::All { rows, .. } => rows.len(),
        Column::Joint(_, v) => v.len() * dof,
    };
    group
        .iter()
        .map(|c| {
            let mut dense = vec![0.0; rows];
            axpy(&mut dense, 1.0, c, dof);
            if base.columns.is_empty() {
                return Some(dense);
            }
            let rhs: Vec<f64> = base.columns.iter().map(|b| dot(b, c, dof, base.rows)).collect();
            let a = solve_scaled(&base.gram, &rhs)?;
            for (b, x) in base.columns.iter().zip(a.iter()) {
                axpy(&mut dense, -x, b, dof);
            }
            Some(dense)
        })
        .collect()
}

/// Holm's step-down procedure: which of `p_values` are rejected at family-wise level `alpha`.
pub fn holm(p_values: &[f64], alpha: f64) -> Vec<bool> {
    let m = p_values.len();
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| p_values[a].total_cmp(&p_values[b]));
    let mut pass = vec![false; m];
    for (rank, &i) in order.iter().enumerate() {
        if p_values[i] <= alpha / (m - rank) as f64 {
            pass[i] = true;
        } else {
            break;
        }
    }
    pass
}

/// The threshold Holm applied to the `rank`-th smallest of `m` p-values (0-based).
pub fn holm_threshold(alpha: f64, m: usize, rank: usize) -> f64 {
    alpha / (m - rank).max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Sums doubled pairwise from the shorter runs' give the meat summed directly over the longer
    /// runs, the leftover samples in the last run, for a sample count that is no power of two.
    #[test]
    fn batch_sums_doubled_pairwise_are_the_sums_over_the_longer_runs() {
        let (k, samples) = (2, 1003);
        let scores: Vec<f64> = (0..samples * k).map(|i| ((i * 7919 % 211) as f64 - 105.0) / 37.0).collect();
        let mut sums = BatchSums { values: scores.clone(), k, length: 1 };
        for length in [1, 2, 4, 8, 16, 32] {
            while sums.length < length {
                sums = sums.doubled(samples);
            }
            let direct = batch_meat(&scores, k, length, samples / length);
            let doubled = sums.meat();
            assert_eq!(doubled.nrows(), k);
            for (a, b) in [(0, 0), (0, 1), (1, 1)] {
                let scale = direct[(a, a)].abs().max(direct[(b, b)].abs());
                assert!((doubled[(a, b)] - direct[(a, b)]).abs() <= 1e-12 * scale, "length {length}");
            }
        }
    }

    #[test]
    fn holm_steps_down_and_stops_at_the_first_failure() {
        // m = 4: thresholds 0.0125, 0.0167, 0.025, 0.05.
        assert_eq!(holm(&[0.01, 0.04, 0.015, 0.03], 0.05), [true, false, true, false]);
        assert_eq!(holm(&[0.02, 0.001], 0.05), [true, true]);
        assert_eq!(holm(&[0.2, 0.03], 0.05), [false, false]);
    }

    #[test]
    fn sparse_and_dense_columns_agree() {
        let dof = 3;
        let a = Column::Joint(1, vec![1.0, 2.0, 3.0]);
        let dense = Column::dense(vec![0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 3.0, 0.0], dof);
        let b = Column::dense((0..9).map(|i| i as f64).collect(), dof);
        assert_eq!(dot(&a, &b, dof, Rows::All), dot(&dense, &b, dof, Rows::All));
        assert_eq!(dot(&a, &a, dof, Rows::Where(&[true, false, true])), 10.0);
    }

    /// What a group explains of the base fit's residual is the drop of the residual sum of
    /// squares from fitting the base alone to fitting both, for dense and one-joint columns.
    #[test]
    fn what_a_group_explains_is_the_drop_of_the_residual() {
        let (dof, samples) = (2, 400);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise = |rng: &mut ChaCha8Rng, n: usize| (0..n).map(|_| rng.random_range(-1.0..1.0)).collect::<Vec<f64>>();
        let base_columns =
            [Column::dense(noise(&mut rng, samples * dof), dof), Column::Joint(0, noise(&mut rng, samples))];
        let group = [Column::Joint(1, noise(&mut rng, samples)), Column::dense(noise(&mut rng, samples * dof), dof)];
        let y = noise(&mut rng, samples * dof);
        let sse = |columns: &[&Column]| {
            let fit = least_squares(columns, &y, dof, Rows::All).unwrap();
            residual(columns, &fit, &y, dof).iter().map(|e| e * e).sum::<f64>()
        };
        let base: Vec<&Column> = base_columns.iter().collect();
        let normal = NormalEquations::over(base.clone(), &y, dof, Rows::All);
        let e0 = residual(&base, &normal.solve().unwrap(), &y, dof);
        let both: Vec<&Column> = base.iter().copied().chain(&group).collect();
        let drop = sse(&base) - sse(&both);
        let group: Vec<&Column> = group.iter().collect();
        let said = explained(&normal, &e0, &group).unwrap();
        assert!((said - drop).abs() < 1e-9 * drop, "{said} against {drop}");
        let empty = NormalEquations::over(vec![], &y, dof, Rows::All);
        let alone = explained(&empty, &y, &group).unwrap();
        assert!((alone - (y.iter().map(|v| v * v).sum::<f64>() - sse(&group))).abs() < 1e-9 * alone);
    }

    /// AR(1) noise `x ← ρx + u`, u uniform on ±1.
    fn ar(rng: &mut ChaCha8Rng, samples: usize, rho: f64) -> Vec<f64> {
        let mut x = 0.0;
        (0..samples)
            .map(|_| {
                x = rho * x + rng.random_range(-1.0..1.0);
                x
            })
            .collect()
    }

    /// One test of a smooth candidate (AR(1), ρ = 0.9) against an offset, on AR(1) residual
    /// noise of correlation `rho` plus `effect` times the candidate.
    fn trial(
        rng: &mut ChaCha8Rng,
        samples: usize,
        rho: f64,
        effect: f64,
        batching: Batching,
    ) -> Result<GroupTest, Untested> {
        let c = ar(rng, samples, 0.9);
        let e: Vec<f64> = ar(rng, samples, rho).iter().zip(&c).map(|(n, c)| n + effect * c).collect();
        let offset = Column::dense(vec![1.0; samples], 1);
        let mean = e.iter().sum::<f64>() / samples as f64;
        let e0: Vec<f64> = e.iter().map(|v| v - mean).collect();
        let base = NormalEquations::over(vec![&offset], &e0, 1, Rows::All);
        test_group(&base, &e0, &[&Column::dense(c, 1)], batching, &[])
    }

    fn rejection_rate(rho: f64, batching: Batching, alpha: f64) -> f64 {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let trials = 400;
        // A test the log cannot support accepts nothing.
        let below =
            (0..trials).filter(|_| trial(&mut rng, 2000, rho, 0.0, batching).is_ok_and(|t| t.p_value < alpha)).count();
        below as f64 / trials as f64
    }

    /// With independent batches and no effect, the test's p-values are uniform: about α of them
    /// fall below α. This is what makes the false-positive rate controllable at all.
    #[test]
    fn the_batch_wald_test_holds_its_level_on_correlated_noise() {
        let rate = rejection_rate(0.9, Batching::Fixed(50), 0.05);
        assert!((0.02..=0.09).contains(&rate), "rejection rate {rate} at α = 0.05");
    }

    /// Batches chosen from the scores hold the level whatever the noise's correlation, from white
    /// to a correlation time of 50 samples, where fixed batches of 5 samples do not.
    #[test]
    fn batches_from_the_scores_hold_the_level_from_white_to_slow_noise() {
        for rho in [0.0, 0.5, 0.9, 0.98] {
            let rate = rejection_rate(rho, Batching::FromScores, 0.05);
            assert!((0.02..=0.09).contains(&rate), "ρ = {rho}: rejection rate {rate} at α = 0.05");
        }
        let short = rejection_rate(0.98, Batching::Fixed(5), 0.05);
        assert!(short > 0.15, "fixed short batches on slow noise: {short}");
    }

    /// A residual that carries a given model's calibration error `z·s·d` (a fixed direction `d`
    /// that correlates with the candidate, `z` standard normal, drawn once per log as a
    /// calibration is) rejects a candidate with no effect far above α; told the error's size
    /// (`known = [s·d]`), the test holds its level.
    #[test]
    fn a_known_calibration_error_keeps_the_level_it_would_break() {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let (trials, samples, alpha, s) = (400, 2000, 0.05, 0.3);
        let (mut blind, mut told) = (0, 0);
        for _ in 0..trials {
            let c = ar(&mut rng, samples, 0.9);
            let d: Vec<f64> = ar(&mut rng, samples, 0.9).iter().zip(&c).map(|(x, c)| x + c).collect();
            let (u1, u2): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random_range(0.0..1.0));
            let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            let e: Vec<f64> = ar(&mut rng, samples, 0.5).iter().zip(&d).map(|(n, d)| n + z * s * d).collect();
            let offset = Column::dense(vec![1.0; samples], 1);
            let mean = e.iter().sum::<f64>() / samples as f64;
            let e0: Vec<f64> = e.iter().map(|v| v - mean).collect();
            let base = NormalEquations::over(vec![&offset], &e0, 1, Rows::All);
            let group = [&Column::dense(c, 1)];
            let known = vec![d.iter().map(|d| s * d).collect::<Vec<f64>>()];
            let rejects = |known: &[Vec<f64>]| {
                test_group(&base, &e0, &group, Batching::FromScores, known).is_ok_and(|t| t.p_value < alpha) as usize
            };
            blind += rejects(&[]);
            told += rejects(&known);
        }
        let (blind, told) = (blind as f64 / trials as f64, told as f64 / trials as f64);
        assert!(blind > 0.5, "without the calibration's error: rejection rate {blind}");
        assert!(told <= 0.09, "with it: rejection rate {told} at α = {alpha}");
    }

    /// The known error's variance is added exactly: along the candidate itself, `s` per unit
    /// coefficient adds `s²` to its variance; orthogonal to it, nothing.
    #[test]
    fn a_known_error_along_the_candidate_adds_its_variance() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let samples = 1000;
        let c = ar(&mut rng, samples, 0.9);
        let mean = c.iter().sum::<f64>() / samples as f64;
        let centred: Vec<f64> = c.iter().map(|v| v - mean).collect();
        let noise = ar(&mut rng, samples, 0.3);
        let noise_mean = noise.iter().sum::<f64>() / samples as f64;
        let e0: Vec<f64> = noise.iter().map(|v| v - noise_mean).collect();
        let offset = Column::dense(vec![1.0; samples], 1);
        let base = NormalEquations::over(vec![&offset], &e0, 1, Rows::All);
        let group = [&Column::dense(c, 1)];
        let sigma = |known: &[Vec<f64>]| test_group(&base, &e0, &group, Batching::Fixed(20), known).unwrap().sigma[0];
        let s = 0.7;
        let along = vec![centred.iter().map(|v| s * v).collect::<Vec<f64>>()];
        let (alone, with) = (sigma(&[]), sigma(&along));
        assert!((with * with - alone * alone - s * s).abs() < 1e-9 * s * s, "{alone} → {with}");
        assert_eq!(sigma(&[vec![1.0; samples]]), alone, "an offset is the model's, not the candidate's");
    }

    /// A candidate that explains the residual exactly where its column lives leaves its scores
    /// nil in every batch: its σ from the batches is zero, which would be F = ∞ (a counterweight
    /// "241.6 ± 0.0 g" was accepted so). It is a direction the data do not test, not a finding;
    /// the same column over a residual with noise where it lives is tested.
    #[test]
    fn a_coefficient_with_no_batch_variance_is_untestable() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (samples, half) = (400, 200);
        let lives = |first: bool| (0..samples).map(move |s| f64::from((s < half) == first));
        let candidate: Vec<f64> = lives(true).enumerate().map(|(s, on)| on * (1.0 + (s as f64 * 0.1).sin())).collect();
        let noise = ar(&mut rng, samples - half, 0.3);
        let noise_mean = noise.iter().sum::<f64>() / noise.len() as f64;
        let mut e0: Vec<f64> = candidate.iter().map(|c| 2.0 * c).collect();
        e0[half..].iter_mut().zip(&noise).for_each(|(e, n)| *e = n - noise_mean);
        let elsewhere = Column::dense(lives(false).collect(), 1);
        let group = [&Column::dense(candidate.clone(), 1)];
        let test = |e0: &[f64]| {
            let base = NormalEquations::over(vec![&elsewhere], e0, 1, Rows::All);
            test_group(&base, e0, &group, Batching::Fixed(20), &[])
        };
        assert!(matches!(test(&e0), Err(Untested::Dependent { .. })), "{:?}", test(&e0));
        let more = ar(&mut rng, half, 0.3);
        e0[..half].iter_mut().zip(&more).for_each(|(e, n)| *e += 0.1 * n);
        let tested = test(&e0).expect("noise where the column lives");
        assert!((tested.coefficients[0] - 2.0).abs() < 0.1 && tested.sigma[0] > 0.0, "{tested:?}");
    }

    /// On a short log (900 samples, as 9 s decimated to 100 Hz) a fixed 2 s batch leaves four
    /// batches and almost no power at the threshold a search over many candidates sets; batches
    /// from the scores find the same effect (about 60 % of the noise's RMS) nearly every time.
    #[test]
    fn batches_from_the_scores_keep_power_on_a_short_log() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let trials = 100;
        let (mut fixed, mut chosen) = (0, 0);
        for _ in 0..trials {
            let mut r = rng.clone();
            fixed += trial(&mut r, 900, 0.5, 0.3, Batching::Fixed(200)).is_ok_and(|t| t.p_value < 1e-4) as usize;
            chosen += trial(&mut rng, 900, 0.5, 0.3, Batching::FromScores).is_ok_and(|t| t.p_value < 1e-4) as usize;
        }
        assert!(chosen >= 90, "found {chosen} of {trials} with batches from the scores");
        assert!(fixed <= 20, "found {fixed} of {trials} with 2 s batches");
    }

    /// A residual that mixes fast noise with a small slow misfit (a closed loop's), against a
    /// slow candidate: the scores' autocorrelation falls fast and then has a long tail that holds
    /// most of their long-run variance. Blocking sees the tail and holds the level; batches sized
    /// on the fast part (8 samples) reject several times too often. The log is 16,000 samples,
    /// about 300 of the scores' correlation times; at 4,000 the rate found is 0.11: a plateau
    /// seen through a dozen batches is still rising a little.
    #[test]
    fn blocking_holds_the_level_when_fast_noise_hides_a_slow_misfit() {
        let rate = |batching: Batching| {
            let mut rng = ChaCha8Rng::seed_from_u64(17);
            let trials = 300;
            let below = (0..trials)
                .filter(|_| {
                    let samples = 16000;
                    let c = ar(&mut rng, samples, 0.99);
                    let slow = ar(&mut rng, samples, 0.99);
                    let e: Vec<f64> = (0..samples).map(|i| 4.0 * rng.random_range(-1.0..1.0) + 0.5 * slow[i]).collect();
                    let offset = Column::dense(vec![1.0; samples], 1);
                    let mean = e.iter().sum::<f64>() / samples as f64;
                    let e0: Vec<f64> = e.iter().map(|v| v - mean).collect();
                    let base = NormalEquations::over(vec![&offset], &e0, 1, Rows::All);
                    test_group(&base, &e0, &[&Column::dense(c, 1)], batching, &[]).is_ok_and(|t| t.p_value < 0.05)
                })
                .count();
            below as f64 / trials as f64
        };
        let chosen = rate(Batching::FromScores);
        let short = rate(Batching::Fixed(8));
        eprintln!("mixture: blocking {chosen}, batches of 8 samples {short}");
        assert!(chosen <= 0.09, "blocking rejects {chosen} at α = 0.05");
        assert!(short >= 0.15, "short batches reject {short}");
    }

    #[test]
    fn too_few_batches_for_the_columns_is_said_so() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let t = trial(&mut rng, 100, 0.0, 0.0, Batching::Fixed(40));
        assert_eq!(t.unwrap_err(), Untested::TooFewBatches { batches: 2, columns: 1 });
    }
}
