//! The LAPACK routines Clarabel calls: `?potrf`, `?potrs`, `?syevr`, `?gesdd`, `?gesvd`, `?gesv`,
//! on faer's factorisations, run sequentially (the matrices Clarabel hands over are small, and a
//! thread pool would cost more than it saves).
//!
//! Where LAPACK leaves part of an array alone, so do these: `?potrf` writes only the triangle it
//! factors, as Clarabel relies on. Where LAPACK says an input is destroyed, these leave it as it
//! was. None needs workspace, so a workspace query answers the minimum (1).

use core::ffi::{c_char, c_int};

use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::evd::{self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_unit_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Mat, MatMut, MatRef, Par};

use super::args::{exported, int, letter, upper, view, view_mut, Real};

/// LAPACK's `INFO` for a bad argument: minus its 1-based position, or 0.
fn bad_argument(checks: &[(bool, i32)]) -> c_int {
    -super::args::first_bad(checks)
}

/// The lower triangle of the symmetric matrix held in `a`'s `upper` (or lower) triangle.
fn lower_of<T: Real>(a: MatRef<'_, T>, upper: bool) -> MatRef<'_, T> {
    if upper {
        a.transpose()
    } else {
        a
    }
}

/// Cholesky factor of the symmetric matrix in `a`'s `upper` (or lower) triangle, written over
/// that triangle only (`Uᵀ U` or `L Lᵀ`). `Err(k)`: the leading minor of order `k` (1-based) is
/// not positive definite (or not a number), and `a` is left unchanged.
pub fn potrf<T: Real>(upper: bool, a: MatMut<'_, T>) -> Result<(), usize> {
    let mut a = a;
    let n = a.nrows();
    let mut l = Mat::<T>::zeros(n, n);
    l.copy_from_triangular_lower(lower_of(a.rb(), upper));
    let mut memory = MemBuffer::new(cholesky_in_place_scratch::<T>(n, Par::Seq, Default::default()));
    cholesky_in_place(l.as_mut(), Default::default(), Par::Seq, MemStack::new(&mut memory), Default::default())
        .map_err(|faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index }| index + 1)?;
    for j in 0..n {
        for i in j..n {
            match upper {
                true => a[(j, i)] = l[(i, j)],
                false => a[(i, j)] = l[(i, j)],
            }
        }
    }
    Ok(())
}

/// Solves `A x = b` for every column of `b`, with `A`'s Cholesky factor from [`potrf`] in `a`'s
/// `upper` (or lower) triangle.
pub fn potrs<T: Real>(upper: bool, a: MatRef<'_, T>, b: MatMut<'_, T>) {
    let mut b = b;
    let l = lower_of(a, upper);
    solve_lower_triangular_in_place(l, b.rb_mut(), Par::Seq);
    solve_upper_triangular_in_place(l.transpose(), b, Par::Seq);
}

/// Which eigenvalues `?syevr` returns.
#[derive(Clone, Copy, Debug)]
pub enum Range<T> {
    All,
    /// Those in the half-open interval `(lower, upper]`.
    Values(T, T),
    /// The `first`-th to `last`-th smallest (0-based, inclusive).
    Indices(usize, usize),
}

/// Eigenvalues of the symmetric matrix in `a`'s `upper` (or lower) triangle, ascending, and with
/// `vectors` their orthonormal eigenvectors as columns; `None` when the iteration does not
/// converge.
pub fn syevr<T: Real>(a: MatRef<'_, T>, upper: bool, range: Range<T>, vectors: bool) -> Option<(Vec<T>, Mat<T>)> {
    let n = a.nrows();
    let mut lower = Mat::<T>::zeros(n, n);
    lower.copy_from_triangular_lower(lower_of(a, upper));
    let mut s = Diag::<T>::zeros(n);
    let mut u = Mat::<T>::zeros(n, if vectors { n } else { 0 });
    let compute = if vectors { ComputeEigenvectors::Yes } else { ComputeEigenvectors::No };
    let mut memory = MemBuffer::new(self_adjoint_evd_scratch::<T>(n, compute, Par::Seq, Default::default()));
    let u_out = if vectors { Some(u.as_mut()) } else { None };
    let stack = MemStack::new(&mut memory);
    self_adjoint_evd(lower.as_ref(), s.as_mut(), u_out, Par::Seq, stack, Default::default()).ok()?;
    let values: Vec<T> = s.column_vector().iter().copied().collect();
    let kept: Vec<usize> = (0..n)
        .filter(|&i| match range {
            Range::All => true,
            Range::Values(lo, hi) => values[i] > lo && values[i] <= hi,
            Range::Indices(first, last) => (first..=last).contains(&i),
        })
        .collect();
    let chosen = Mat::<T>::from_fn(n, if vectors { kept.len() } else { 0 }, |i, j| u[(i, kept[j])]);
    Some((kept.iter().map(|&i| values[i]).collect(), chosen))
}

/// What an SVD writes of one factor: the whole square factor (`'A'`), its first min(m, n)
/// vectors (`'S'`), those vectors over the input matrix (`'O'`), or nothing (`'N'`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    All,
    Thin,
    Overwrite,
    Skip,
}

impl Job {
    pub fn of(letter: u8) -> Option<Job> {
        match letter {
            b'A' => Some(Job::All),
            b'S' => Some(Job::Thin),
            b'O' => Some(Job::Overwrite),
            b'N' => Some(Job::Skip),
            _ => None,
        }
    }

    /// How many vectors of a factor the job writes to its own array: `all` (m or n) for the
    /// whole factor, `k` = min(m, n) for the thin one, none otherwise.
    fn vectors(self, all: i64, k: i64) -> i64 {
        match self {
            Job::All => all,
            Job::Thin => k,
            Job::Overwrite | Job::Skip => 0,
        }
    }
}

/// The SVD `a = U Σ Vᵀ` with `full` square factors or thin ones: singular values descending,
/// `U`, and `V` (not transposed); `None` when the iteration does not converge.
pub fn svd_of<T: Real>(a: MatRef<'_, T>, full: bool) -> Option<(Vec<T>, Mat<T>, Mat<T>)> {
    let (m, n) = a.shape();
    let k = m.min(n);
    let (cols_u, cols_v) = if full { (m, n) } else { (k, k) };
    let compute = if full { ComputeSvdVectors::Full } else { ComputeSvdVectors::Thin };
    let (mut u, mut v, mut s) = (Mat::<T>::zeros(m, cols_u), Mat::<T>::zeros(n, cols_v), Diag::<T>::zeros(k));
    let mut memory = MemBuffer::new(svd_scratch::<T>(m, n, compute, compute, Par::Seq, Default::default()));
    let stack = MemStack::new(&mut memory);
    svd(a, s.as_mut(), Some(u.as_mut()), Some(v.as_mut()), Par::Seq, stack, Default::default()).ok()?;
    Some((s.column_vector().iter().copied().collect(), u, v))
}

/// Solves `a x = b` by LU with partial pivoting, `a` overwritten by its factors `P a = L U` (L's
/// unit diagonal not stored) and `pivots` by LAPACK's row interchanges (1-based: row `i` was
/// swapped with row `pivots[i]`). `Err(k)`: `U[k, k]` (1-based) is exactly zero, and `b` is
/// left unsolved.
pub fn gesv<T: Real>(a: MatMut<'_, T>, pivots: &mut [c_int], b: MatMut<'_, T>) -> Result<(), usize> {
    let (mut a, mut b) = (a, b);
    let n = a.nrows();
    let (mut forward, mut inverse) = (vec![0usize; n], vec![0usize; n]);
    let mut memory = MemBuffer::new(lu_in_place_scratch::<usize, T>(n, n, Par::Seq, Default::default()));
    let stack = MemStack::new(&mut memory);
    lu_in_place(a.rb_mut(), &mut forward, &mut inverse, Par::Seq, stack, Default::default());
    interchanges(&forward, pivots);
    if let Some(k) = (0..n).find(|&k| a[(k, k)] == T::ZERO) {
        return Err(k + 1);
    }
    for (i, &p) in pivots.iter().enumerate() {
        let p = p as usize - 1;
        if p != i {
            for j in 0..b.ncols() {
                let (x, y) = (b[(i, j)], b[(p, j)]);
                b[(i, j)] = y;
                b[(p, j)] = x;
            }
        }
    }
    solve_unit_lower_triangular_in_place(a.rb(), b.rb_mut(), Par::Seq);
    solve_upper_triangular_in_place(a.rb(), b, Par::Seq);
    Ok(())
}

/// LAPACK's sequence of row interchanges for a row permutation (`order[i]`: the original row
/// now at position `i`): swapping row `i` with row `pivots[i]` (1-based), for `i` in turn,
/// reproduces it. Row `i` is final after step `i`, so each step finds where `order[i]` is now.
fn interchanges(order: &[usize], pivots: &mut [c_int]) {
    let n = order.len();
    let (mut at, mut position): (Vec<usize>, Vec<usize>) = ((0..n).collect(), (0..n).collect());
    for i in 0..n {
        let j = position[order[i]];
        pivots[i] = (j + 1) as c_int;
        let (row_i, row_j) = (at[i], at[j]);
        at.swap(i, j);
        position[row_i] = j;
        position[row_j] = i;
    }
}

exported! {
    /// LAPACK `?potrf`: the Cholesky factor, over one triangle.
    dpotrf_, spotrf_ (
        uplo: *const c_char,
        n: *const c_int,
        a: *mut T,
        lda: *const c_int,
        info: *mut c_int,
    ) {
        let up = upper(letter(uplo));
        let (n, lda) = (int(n), int(lda));
        *info = bad_argument(&[(up.is_some(), 1), (n >= 0, 2), (lda >= n.max(1), 4)]);
        if *info == 0 {
            *info = potrf(up == Some(true), view_mut(a, n, n, lda)).err().unwrap_or(0) as c_int;
        }
    }
}

exported! {
    /// LAPACK `?potrs`: solves with a factor from `?potrf`.
    dpotrs_, spotrs_ (
        uplo: *const c_char,
        n: *const c_int,
        nrhs: *const c_int,
        a: *const T,
        lda: *const c_int,
        b: *mut T,
        ldb: *const c_int,
        info: *mut c_int,
    ) {
        let up = upper(letter(uplo));
        let (n, nrhs, lda, ldb) = (int(n), int(nrhs), int(lda), int(ldb));
        *info = bad_argument(&[(up.is_some(), 1), (n >= 0, 2), (nrhs >= 0, 3), (lda >= n.max(1), 5), (ldb >= n.max(1), 7)]);
        if *info == 0 {
            potrs(up == Some(true), view(a, n, n, lda), view_mut(b, n, nrhs, ldb));
        }
    }
}

exported! {
    /// LAPACK `?syevr`: eigenvalues and eigenvectors of a symmetric matrix.
    dsyevr_, ssyevr_ (
        jobz: *const c_char,
        range: *const c_char,
        uplo: *const c_char,
        n: *const c_int,
        a: *mut T,
        lda: *const c_int,
        vl: *const T,
        vu: *const T,
        il: *const c_int,
        iu: *const c_int,
        _abstol: *const T,
        m: *mut c_int,
        w: *mut T,
        z: *mut T,
        ldz: *const c_int,
        isuppz: *mut c_int,
        work: *mut T,
        lwork: *const c_int,
        iwork: *mut c_int,
        liwork: *const c_int,
        info: *mut c_int,
    ) {
        let (vectors, which, up) = (letter(jobz), letter(range), upper(letter(uplo)));
        let (n, lda, il, iu, ldz, lwork, liwork) = (int(n), int(lda), int(il), int(iu), int(ldz), int(lwork), int(liwork));
        let query = lwork == -1 || liwork == -1;
        *info = bad_argument(&[
            (vectors == b'V' || vectors == b'N', 1),
            (matches!(which, b'A' | b'V' | b'I'), 2),
            (up.is_some(), 3),
            (n >= 0, 4),
            (lda >= n.max(1), 6),
            (which != b'V' || n == 0 || *vl < *vu, 8),
            (which != b'I' || (il >= 1 && il <= n.max(1)), 9),
            (which != b'I' || (iu >= il.min(n) && iu <= n), 10),
            (ldz >= 1 && (vectors != b'V' || ldz >= n), 15),
            (query || lwork >= 1, 18),
            (query || liwork >= 1, 20),
        ]);
        if *info != 0 {
            return;
        }
        if query {
            *work = T::ONE;
            *iwork = 1;
            return;
        }
        let range = match which {
            b'A' => Range::All,
            b'V' => Range::Values(*vl, *vu),
            _ => Range::Indices((il - 1).max(0) as usize, (iu - 1).max(0) as usize),
        };
        if n == 0 || (which == b'I' && iu < il) {
            *m = 0;
            return;
        }
        let Some((values, vecs)) = syevr(view(a, n, n, lda), up == Some(true), range, vectors == b'V') else {
            *info = 1;
            return;
        };
        *m = values.len() as c_int;
        core::ptr::copy_nonoverlapping(values.as_ptr(), w, values.len());
        if vectors == b'V' {
            let mut out = view_mut(z, n, values.len() as i64, ldz);
            out.copy_from(&vecs);
            // The support of each eigenvector: its first and last non-zero rows (1-based).
            for j in 0..values.len() {
                let nonzero: Vec<usize> = (0..n as usize).filter(|&i| vecs[(i, j)] != T::ZERO).collect();
                *isuppz.add(2 * j) = nonzero.first().map_or(1, |&i| i + 1) as c_int;
                *isuppz.add(2 * j + 1) = nonzero.last().map_or(0, |&i| i + 1) as c_int;
            }
        }
    }
}

/// The SVD behind `?gesdd` and `?gesvd`, once their arguments are checked (`info` holds the
/// check's result, and nothing is done when it is not 0): answers a workspace query (`lwork`
/// −1: none is needed), or writes `s`, and `U` and `Vᵀ` where the jobs ask (over `a` for
/// [`Job::Overwrite`]); `info` 1 when it does not converge.
///
/// # Safety
/// The pointers are valid for the dimensions given, as LAPACK defines them for the jobs.
#[allow(clippy::too_many_arguments)]
unsafe fn svd_entry<T: Real>(
    (job_u, job_vt): (Job, Job),
    (m, n): (i64, i64),
    (a, lda): (*mut T, i64),
    s: *mut T,
    (u, ldu): (*mut T, i64),
    (vt, ldvt): (*mut T, i64),
    (work, lwork): (*mut T, i64),
    info: *mut c_int,
) {
    if *info != 0 {
        return;
    }
    if lwork == -1 {
        *work = T::ONE;
        return;
    }
    let k = m.min(n);
    if k == 0 {
        return;
    }
    let full = job_u == Job::All || job_vt == Job::All;
    let Some((values, u_full, v_full)) = svd_of(view(a, m, n, lda), full) else {
        *info = 1;
        return;
    };
    core::ptr::copy_nonoverlapping(values.as_ptr(), s, values.len());
    let u_target = match job_u {
        Job::Skip => None,
        Job::Overwrite => Some(view_mut(a, m, k, lda)),
        job => Some(view_mut(u, m, job.vectors(m, k), ldu)),
    };
    let vt_target = match job_vt {
        Job::Skip => None,
        Job::Overwrite => Some(view_mut(a, k, n, lda)),
        job => Some(view_mut(vt, job.vectors(n, k), n, ldvt)),
    };
    if let Some(mut target) = u_target {
        let cols = target.ncols();
        target.copy_from(u_full.get(.., ..cols));
    }
    if let Some(mut target) = vt_target {
        let rows = target.nrows();
        target.copy_from(v_full.get(.., ..rows).transpose());
    }
}

exported! {
    /// LAPACK `?gesdd`: singular value decomposition.
    dgesdd_, sgesdd_ (
        jobz: *const c_char,
        m: *const c_int,
        n: *const c_int,
        a: *mut T,
        lda: *const c_int,
        s: *mut T,
        u: *mut T,
        ldu: *const c_int,
        vt: *mut T,
        ldvt: *const c_int,
        work: *mut T,
        lwork: *const c_int,
        _iwork: *mut c_int,
        info: *mut c_int,
    ) {
        let job = Job::of(letter(jobz));
        let (m, n, lda, ldu, ldvt, lwork) = (int(m), int(n), int(lda), int(ldu), int(ldvt), int(lwork));
        let wide = m < n;
        // 'O' overwrites A with U when m ≥ n, and with Vᵀ otherwise; the other factor goes out.
        let (job_u, job_vt) = match job {
            Some(Job::Overwrite) if wide => (Job::All, Job::Overwrite),
            Some(Job::Overwrite) => (Job::Overwrite, Job::All),
            Some(job) => (job, job),
            None => (Job::Skip, Job::Skip),
        };
        let k = m.min(n);
        *info = bad_argument(&[
            (job.is_some(), 1),
            (m >= 0, 2),
            (n >= 0, 3),
            (lda >= m.max(1), 5),
            (ldu >= 1 && (!matches!(job_u, Job::All | Job::Thin) || ldu >= m), 8),
            (ldvt >= job_vt.vectors(n, k).max(1), 10),
            (lwork == -1 || lwork >= 1, 12),
        ]);
        svd_entry((job_u, job_vt), (m, n), (a, lda), s, (u, ldu), (vt, ldvt), (work, lwork), info);
    }
}

exported! {
    /// LAPACK `?gesvd`: singular value decomposition.
    dgesvd_, sgesvd_ (
        jobu: *const c_char,
        jobvt: *const c_char,
        m: *const c_int,
        n: *const c_int,
        a: *mut T,
        lda: *const c_int,
        s: *mut T,
        u: *mut T,
        ldu: *const c_int,
        vt: *mut T,
        ldvt: *const c_int,
        work: *mut T,
        lwork: *const c_int,
        info: *mut c_int,
    ) {
        let (job_u, job_vt) = (Job::of(letter(jobu)), Job::of(letter(jobvt)));
        let (m, n, lda, ldu, ldvt, lwork) = (int(m), int(n), int(lda), int(ldu), int(ldvt), int(lwork));
        let both_overwrite = job_u == Some(Job::Overwrite) && job_vt == Some(Job::Overwrite);
        let (checked_u, checked_vt) = (job_u.unwrap_or(Job::Skip), job_vt.unwrap_or(Job::Skip));
        let k = m.min(n);
        *info = bad_argument(&[
            (job_u.is_some(), 1),
            (job_vt.is_some() && !both_overwrite, 2),
            (m >= 0, 3),
            (n >= 0, 4),
            (lda >= m.max(1), 6),
            (ldu >= 1 && (!matches!(checked_u, Job::All | Job::Thin) || ldu >= m), 9),
            (ldvt >= checked_vt.vectors(n, k).max(1), 11),
            (lwork == -1 || lwork >= 1, 13),
        ]);
        let jobs = (checked_u, checked_vt);
        svd_entry(jobs, (m, n), (a, lda), s, (u, ldu), (vt, ldvt), (work, lwork), info);
    }
}

exported! {
    /// LAPACK `?gesv`: solves a general system by LU with partial pivoting.
    dgesv_, sgesv_ (
        n: *const c_int,
        nrhs: *const c_int,
        a: *mut T,
        lda: *const c_int,
        ipiv: *mut c_int,
        b: *mut T,
        ldb: *const c_int,
        info: *mut c_int,
    ) {
        let (n, nrhs, lda, ldb) = (int(n), int(nrhs), int(lda), int(ldb));
        *info = bad_argument(&[(n >= 0, 1), (nrhs >= 0, 2), (lda >= n.max(1), 4), (ldb >= n.max(1), 7)]);
        if *info != 0 || n == 0 {
            return;
        }
        let pivots = core::slice::from_raw_parts_mut(ipiv, n as usize);
        *info = gesv(view_mut(a, n, n, lda), pivots, view_mut(b, n, nrhs, ldb)).err().unwrap_or(0) as c_int;
    }
}

#[cfg(test)]
mod tests {
    //! Properties that need no reference; tests/python/test_blas_lapack.py checks every routine
    //! against scipy's LAPACK and BLAS.
    use super::*;

    fn spd(n: usize) -> Mat<f64> {
        Mat::from_fn(n, n, |i, j| if i == j { n as f64 + 1.0 } else { 1.0 / (1.0 + (i + j) as f64) })
    }

    #[test]
    fn potrf_writes_its_triangle_only_and_the_factor_reproduces_the_matrix() {
        let a = spd(5);
        for upper in [false, true] {
            let mut stored = a.clone();
            let other = |i: usize, j: usize| if upper { i > j } else { i < j };
            for (i, j) in (0..5).flat_map(|i| (0..5).map(move |j| (i, j))).filter(|&(i, j)| other(i, j)) {
                stored[(i, j)] = f64::NAN;
            }
            potrf(upper, stored.as_mut()).unwrap();
            let l = Mat::from_fn(5, 5, |i, j| match (upper, i >= j) {
                (false, true) => stored[(i, j)],
                (true, true) => stored[(j, i)],
                _ => 0.0,
            });
            let product = &l * l.transpose();
            for (i, j) in (0..5).flat_map(|i| (0..5).map(move |j| (i, j))) {
                assert!((product[(i, j)] - a[(i, j)]).abs() < 1e-12);
                assert_eq!(stored[(i, j)].is_nan(), other(i, j), "({i}, {j})");
            }
        }
    }

    #[test]
    fn potrf_reports_the_first_pivot_that_is_not_a_positive_number() {
        for (k, bad) in [(1, -1.0), (3, f64::NAN), (4, 0.0)] {
            let mut a = spd(5);
            a[(k - 1, k - 1)] = bad;
            let before = a.clone();
            assert_eq!(potrf(false, a.as_mut()), Err(k));
            assert!((0..25).all(|x| a[(x / 5, x % 5)].to_bits() == before[(x / 5, x % 5)].to_bits()));
        }
    }

    #[test]
    fn the_interchanges_reproduce_the_permutation() {
        let order = [3, 0, 4, 1, 2];
        let mut pivots = [0; 5];
        interchanges(&order, &mut pivots);
        let mut rows: Vec<usize> = (0..5).collect();
        for (i, &p) in pivots.iter().enumerate() {
            rows.swap(i, p as usize - 1);
        }
        assert_eq!(rows, order);
    }
}
