//! Dense linear algebra of the large problems, on faer: stacked regressors, Gram matrices,
//! covariances and the small systems solved from them. nalgebra stays for the fixed-size spatial
//! types of the model ([`crate::spatial`], the kinematics); every matrix whose size comes from the
//! data, the parameters or the number of joints is a [`faer::Mat`], so that no values are copied
//! between two libraries.
//!
//! Only what several modules share lives here; a module's own use of faer stays in that module.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::solvers::Solve;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Mat, MatMut, MatRef, Par};

/// `x · y` in four interleaved partial sums: a single running sum cannot be vectorised, because
/// reordering it would change the rounding.
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut sums = [0.0; 4];
    let (x4, y4) = (x.chunks_exact(4), y.chunks_exact(4));
    let tail: f64 = x4.remainder().iter().zip(y4.remainder()).map(|(a, b)| a * b).sum();
    for (a, b) in x4.zip(y4) {
        for l in 0..4 {
            sums[l] += a[l] * b[l];
        }
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3]) + tail
}

/// `y += a·x`.
pub fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

/// `m v` for a vector given as a slice.
pub fn times(m: MatRef<'_, f64>, v: &[f64]) -> Vec<f64> {
    (0..m.nrows()).map(|i| (0..m.ncols()).map(|j| m[(i, j)] * v[j]).sum()).collect()
}

/// What [`solve_gram`] does with a column the data never touch (a zero on the Gram matrix's
/// diagonal).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unseen {
    /// Its coefficient is zero: a direction the data cannot see, such as a payload's first moment
    /// along a joint axis, is no reason to refuse the others.
    Pinned,
    /// The system has no solution.
    Refused,
}

/// `G x = b` for a Gram matrix `G`, by Cholesky on `G` scaled to a unit diagonal, so that columns
/// in N·m, N and rad/s weigh alike; `None` where it is singular (or has an unseen column that
/// `unseen` refuses).
pub fn solve_gram(g: MatRef<'_, f64>, b: &[f64], unseen: Unseen) -> Option<Vec<f64>> {
    let p = g.nrows();
    let d: Vec<f64> = (0..p).map(|i| g[(i, i)].sqrt()).collect();
    if d.iter().any(|x| x.is_nan()) || (unseen == Unseen::Refused && d.contains(&0.0)) {
        return None;
    }
    let pinned = |i: usize| d[i] == 0.0;
    let scaled = Mat::from_fn(p, p, |i, j| match (pinned(i), pinned(j)) {
        (false, false) => g[(i, j)] / (d[i] * d[j]),
        _ => f64::from(i == j),
    });
    let mut x = Mat::from_fn(p, 1, |i, _| if pinned(i) { 0.0 } else { b[i] / d[i] });
    cholesky_solve(&cholesky(scaled.as_ref())?, x.as_mut());
    let x: Vec<f64> = (0..p).map(|i| if pinned(i) { 0.0 } else { x[(i, 0)] / d[i] }).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// `m⁻¹` by LU with full pivoting; `None` where `m` is singular (a zero pivot) or the inverse
/// is not finite.
pub fn inverse(m: MatRef<'_, f64>) -> Option<Mat<f64>> {
    solve(m, Mat::identity(m.nrows(), m.nrows()).as_ref())
}

/// `m⁻¹ rhs` by LU with full pivoting; `None` where `m` is singular (a zero pivot) or the result
/// is not finite.
pub fn solve(m: MatRef<'_, f64>, rhs: MatRef<'_, f64>) -> Option<Mat<f64>> {
    let lu = m.full_piv_lu();
    let u = lu.U();
    if (0..u.nrows()).any(|i| u[(i, i)] == 0.0) {
        return None;
    }
    let x = lu.solve(rhs);
    finite(x.as_ref()).then_some(x)
}

/// The inverse of a symmetric positive-definite `m` by Cholesky; `None` where it is not.
pub fn spd_inverse(m: MatRef<'_, f64>) -> Option<Mat<f64>> {
    let mut inverse = Mat::identity(m.nrows(), m.nrows());
    cholesky_solve(&cholesky(m)?, inverse.as_mut());
    finite(inverse.as_ref()).then_some(inverse)
}

/// The lower Cholesky factor of a symmetric positive-definite `m` (its lower triangle is read);
/// `None` where it is not. Factored on the calling thread: these matrices are small, and called
/// at every step of a simulated closed loop, where handing each to faer's thread pool cost more
/// in waking threads than the factorisation itself (an IDIM-IV fit took 12 s of system time
/// against 0.6 s).
pub fn cholesky(m: MatRef<'_, f64>) -> Option<Mat<f64>> {
    let n = m.nrows();
    let mut l = Mat::zeros(n, n);
    l.copy_from_triangular_lower(m);
    let mut memory = MemBuffer::new(cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default()));
    cholesky_in_place(l.as_mut(), Default::default(), Par::Seq, MemStack::new(&mut memory), Default::default()).ok()?;
    // The factorisation works in the strict upper triangle too; L is the lower one alone.
    for j in 1..n {
        l.col_mut(j).subrows_mut(0, j).fill(0.0);
    }
    Some(l)
}

/// `L Lᵀ x = b` in place, `L` from [`cholesky`].
pub fn cholesky_solve(l: &Mat<f64>, mut b: MatMut<'_, f64>) {
    solve_lower_triangular_in_place(l.as_ref(), b.as_mut(), Par::Seq);
    solve_upper_triangular_in_place(l.transpose(), b, Par::Seq);
}

/// The ratio of `m`'s largest singular value to its smallest (NaN where they cannot be computed).
pub fn condition_number(m: MatRef<'_, f64>) -> f64 {
    match m.singular_values() {
        Ok(s) if !s.is_empty() => s[0] / s[s.len() - 1],
        _ => f64::NAN,
    }
}

/// The right singular vector of `m`'s smallest singular value: the direction `m` shrinks most.
pub fn weakest_direction(m: MatRef<'_, f64>) -> Option<Vec<f64>> {
    let svd = m.svd().ok()?;
    let (s, v) = (svd.S().column_vector(), svd.V());
    let smallest = (0..s.nrows()).min_by(|&a, &b| s[a].total_cmp(&s[b]))?;
    Some((0..v.nrows()).map(|i| v[(i, smallest)]).collect())
}

/// The columns of an `L` with `L Lᵀ = covariance`, for a symmetric positive semi-definite
/// covariance, singular or not: its eigenvectors scaled by the square roots of its positive
/// eigenvalues (empty where the decomposition fails).
pub fn psd_factor(covariance: &Mat<f64>) -> Vec<Vec<f64>> {
    let Ok(eigen) = covariance.self_adjoint_eigen(faer::Side::Lower) else {
        return vec![];
    };
    let (s, u) = (eigen.S().column_vector(), eigen.U());
    (0..s.nrows()).filter(|&e| s[e] > 0.0).map(|e| (0..u.nrows()).map(|i| s[e].sqrt() * u[(i, e)]).collect()).collect()
}

/// `m` row-major, if it is `n × n` (empty otherwise): how a model file keeps a covariance.
pub fn square_row_major(m: MatRef<'_, f64>, n: usize) -> Vec<f64> {
    match (m.nrows(), m.ncols()) == (n, n) {
        true => (0..n * n).map(|i| m[(i / n, i % n)]).collect(),
        false => vec![],
    }
}

/// The square roots of a covariance's diagonal (a round-off negative reads as zero).
pub fn standard_deviations(covariance: MatRef<'_, f64>) -> Vec<f64> {
    (0..covariance.nrows()).map(|i| covariance[(i, i)].max(0.0).sqrt()).collect()
}

fn finite(m: MatRef<'_, f64>) -> bool {
    (0..m.ncols()).all(|j| (0..m.nrows()).all(|i| m[(i, j)].is_finite()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scaled Cholesky solve against the system it solves, with columns of very different
    /// scales, and an unseen column pinned or refused.
    #[test]
    fn a_gram_system_is_solved_and_an_unseen_column_pinned_or_refused() {
        let x = Mat::from_fn(50, 3, |i, j| [1e3, 1.0, 1e-3][j] * ((i * (j + 2)) as f64 * 0.37).sin());
        let g = x.transpose() * &x;
        let b = [1.0, -2.0, 0.5];
        let solution = solve_gram(g.as_ref(), &b, Unseen::Refused).unwrap();
        let back = times(g.as_ref(), &solution);
        assert!(back.iter().zip(&b).all(|(a, b)| (a - b).abs() < 1e-9), "{back:?}");
        let mut with_zero = Mat::zeros(4, 4);
        with_zero.submatrix_mut(0, 0, 3, 3).copy_from(&g);
        assert!(solve_gram(with_zero.as_ref(), &[1.0, -2.0, 0.5, 7.0], Unseen::Refused).is_none());
        let pinned = solve_gram(with_zero.as_ref(), &[1.0, -2.0, 0.5, 7.0], Unseen::Pinned).unwrap();
        assert_eq!(pinned[3], 0.0);
        assert!(pinned[..3].iter().zip(&solution).all(|(a, b)| (a - b).abs() <= 1e-12 * b.abs().max(1.0)));
    }

    /// The factor is lower triangular and gives back the matrix, at a size where faer's
    /// factorisation writes into the upper triangle as it works.
    #[test]
    fn the_cholesky_factor_is_lower_triangular_and_gives_the_matrix_back() {
        let n = 40;
        let x = Mat::from_fn(3 * n, n, |i, j| ((i * 7 + j * 13) as f64 * 0.61).sin() + f64::from(i == j));
        let m = x.transpose() * &x;
        let l = cholesky(m.as_ref()).unwrap();
        assert!((0..n).all(|j| (0..j).all(|i| l[(i, j)] == 0.0)), "entries above the diagonal");
        let back = &l * l.transpose();
        let scale = (0..n).map(|i| m[(i, i)]).fold(0.0, f64::max);
        assert!((0..n).all(|i| (0..n).all(|j| (back[(i, j)] - m[(i, j)]).abs() < 1e-12 * scale)));
    }

    #[test]
    fn a_singular_matrix_has_no_inverse_and_a_regular_one_its_own() {
        let singular = Mat::from_fn(3, 3, |i, j| (i + 1) as f64 * (j + 1) as f64);
        assert!(inverse(singular.as_ref()).is_none());
        assert!(spd_inverse(singular.as_ref()).is_none());
        let m = Mat::from_fn(3, 3, |i, j| if i == j { 4.0 } else { 1.0 / (1 + i + j) as f64 });
        for inv in [inverse(m.as_ref()).unwrap(), spd_inverse(m.as_ref()).unwrap()] {
            let product = &m * &inv;
            let off = (0..3).flat_map(|i| (0..3).map(move |j| (i, j)));
            assert!(off.clone().all(|(i, j)| (product[(i, j)] - f64::from(i == j)).abs() < 1e-14));
        }
    }

    /// diag(3, 2, 0.5) rotated: its condition number is 6, and its weakest direction the rotated
    /// third axis (up to sign).
    #[test]
    fn condition_number_and_weakest_direction_of_a_known_matrix() {
        let (c, s) = (0.6, 0.8);
        let rotation = Mat::from_fn(3, 3, |i, j| [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]][i][j]);
        let scales = Mat::from_fn(3, 3, |i, j| if i == j { [3.0, 2.0, 0.5][i] } else { 0.0 });
        let m = &scales * rotation.transpose();
        assert!((condition_number(m.as_ref()) - 6.0).abs() < 1e-12);
        let v = weakest_direction(m.as_ref()).unwrap();
        assert!((v[2].abs() - 1.0).abs() < 1e-12 && v[0].abs() < 1e-12, "{v:?}");
    }

    #[test]
    fn dot_and_axpy_agree_with_the_plain_sums() {
        let x: Vec<f64> = (0..11).map(|i| i as f64 * 0.5 - 1.0).collect();
        let y: Vec<f64> = (0..11).map(|i| (i * i) as f64 - 3.0).collect();
        let plain: f64 = x.iter().zip(&y).map(|(a, b)| a * b).sum();
        assert!((dot(&x, &y) - plain).abs() < 1e-12 * plain.abs());
        let mut z = y.clone();
        axpy(&mut z, 2.0, &x);
        assert!(z.iter().zip(x.iter().zip(&y)).all(|(z, (x, y))| *z == y + 2.0 * x));
    }

    /// `L Lᵀ` is the covariance factored, singular or not.
    #[test]
    fn a_factor_of_a_singular_covariance_rebuilds_it() {
        let c = Mat::from_fn(3, 3, |i, j| [[4.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 9.0]][i][j]);
        let l = psd_factor(&c);
        for i in 0..3 {
            for j in 0..3 {
                let back: f64 = l.iter().map(|v| v[i] * v[j]).sum();
                assert!((back - c[(i, j)]).abs() < 1e-12, "({i}, {j}): {back}");
            }
        }
    }
}
