//! The BLAS routines Clarabel calls: `?gemm`, `?gemv`, `?symv`, `?syrk`, `?syr2k`, with the
//! reference BLAS's semantics (a β of zero never reads the output, so NaN there does not spread;
//! the symmetric routines read and write only the named triangle).

use core::ffi::{c_char, c_int};

use faer::linalg::matmul::matmul;
use faer::reborrow::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef, Par};

use super::args::{
    exported, first_bad, int, letter, transposed, upper, vector, vector_mut, view, view_mut, xerbla, Real,
};

/// `c ← β c`, with `β = 0` writing zeros without reading `c`.
fn scale<T: Real>(beta: T, c: MatMut<'_, T>) {
    let mut c = c;
    for j in 0..c.ncols() {
        for i in 0..c.nrows() {
            c[(i, j)] = if beta == T::ZERO { T::ZERO } else { beta * c[(i, j)] };
        }
    }
}

/// `c ← α a b + β c`.
pub fn gemm<T: Real>(alpha: T, a: MatRef<'_, T>, b: MatRef<'_, T>, beta: T, c: MatMut<'_, T>) {
    let mut c = c;
    if beta != T::ONE {
        scale(beta, c.rb_mut());
    }
    if alpha != T::ZERO && a.ncols() > 0 {
        matmul(c, Accum::Add, a, b, alpha, Par::Seq);
    }
}

/// Element `(i, j)` of the symmetric matrix whose `upper` (or lower) triangle `a` holds.
fn symmetric<T: Real>(a: MatRef<'_, T>, upper: bool, i: usize, j: usize) -> T {
    match (i <= j) == upper {
        true => a[(i, j)],
        false => a[(j, i)],
    }
}

/// `y ← α a x + β y` for the symmetric `a` held in its `upper` (or lower) triangle.
pub fn symv<T: Real>(upper: bool, alpha: T, a: MatRef<'_, T>, x: MatRef<'_, T>, beta: T, y: MatMut<'_, T>) {
    let mut y = y;
    let n = a.nrows();
    let ax: Vec<T> =
        (0..n).map(|i| (0..n).fold(T::ZERO, |sum, j| sum + symmetric(a, upper, i, j) * x[(j, 0)])).collect();
    scale(beta, y.rb_mut());
    if alpha != T::ZERO {
        for (i, v) in ax.into_iter().enumerate() {
            y[(i, 0)] += alpha * v;
        }
    }
}

/// `c ← α p + β c` on the `upper` (or lower) triangle of `c` only.
fn update_triangle<T: Real>(upper: bool, alpha: T, p: MatRef<'_, T>, beta: T, c: MatMut<'_, T>) {
    let mut c = c;
    let n = c.nrows();
    for j in 0..n {
        let rows = if upper { 0..j + 1 } else { j..n };
        for i in rows {
            let kept = if beta == T::ZERO { T::ZERO } else { beta * c[(i, j)] };
            c[(i, j)] = if alpha == T::ZERO { kept } else { kept + alpha * p[(i, j)] };
        }
    }
}

/// `c ← α a aᵀ + β c` on one triangle; `a` is already `op(a)` (n × k).
pub fn syrk<T: Real>(upper: bool, alpha: T, a: MatRef<'_, T>, beta: T, c: MatMut<'_, T>) {
    let n = a.nrows();
    let mut p = Mat::<T>::zeros(n, n);
    if alpha != T::ZERO && a.ncols() > 0 {
        matmul(p.as_mut(), Accum::Replace, a, a.transpose(), T::ONE, Par::Seq);
    }
    update_triangle(upper, alpha, p.as_ref(), beta, c);
}

/// `c ← α (a bᵀ + b aᵀ) + β c` on one triangle; `a` and `b` are already `op(·)` (n × k).
pub fn syr2k<T: Real>(upper: bool, alpha: T, a: MatRef<'_, T>, b: MatRef<'_, T>, beta: T, c: MatMut<'_, T>) {
    let n = a.nrows();
    let mut p = Mat::<T>::zeros(n, n);
    if alpha != T::ZERO && a.ncols() > 0 {
        matmul(p.as_mut(), Accum::Replace, a, b.transpose(), T::ONE, Par::Seq);
        matmul(p.as_mut(), Accum::Add, b, a.transpose(), T::ONE, Par::Seq);
    }
    update_triangle(upper, alpha, p.as_ref(), beta, c);
}

/// `op(x)` of a stored `rows × cols` matrix: its transpose when `t`.
fn op<T>(x: MatRef<'_, T>, t: bool) -> MatRef<'_, T> {
    if t {
        x.transpose()
    } else {
        x
    }
}

exported! {
    /// BLAS `?gemm`: `C ← α op(A) op(B) + β C`.
    dgemm_, sgemm_ (
        transa: *const c_char,
        transb: *const c_char,
        m: *const c_int,
        n: *const c_int,
        k: *const c_int,
        alpha: *const T,
        a: *const T,
        lda: *const c_int,
        b: *const T,
        ldb: *const c_int,
        beta: *const T,
        c: *mut T,
        ldc: *const c_int,
    ) {
        let (ta, tb) = (transposed(letter(transa)), transposed(letter(transb)));
        let (m, n, k, lda, ldb, ldc) = (int(m), int(n), int(k), int(lda), int(ldb), int(ldc));
        let (rows_a, rows_b) = (if ta == Some(true) { k } else { m }, if tb == Some(true) { n } else { k });
        xerbla(
            "gemm",
            first_bad(&[
                (ta.is_some(), 1),
                (tb.is_some(), 2),
                (m >= 0, 3),
                (n >= 0, 4),
                (k >= 0, 5),
                (lda >= rows_a.max(1), 8),
                (ldb >= rows_b.max(1), 10),
                (ldc >= m.max(1), 13),
            ]),
        );
        let (ta, tb) = (ta == Some(true), tb == Some(true));
        let a = op(view(a, rows_a, if ta { m } else { k }, lda), ta);
        let b = op(view(b, rows_b, if tb { k } else { n }, ldb), tb);
        gemm(*alpha, a, b, *beta, view_mut(c, m, n, ldc));
    }
}

exported! {
    /// BLAS `?gemv`: `y ← α op(A) x + β y`.
    dgemv_, sgemv_ (
        trans: *const c_char,
        m: *const c_int,
        n: *const c_int,
        alpha: *const T,
        a: *const T,
        lda: *const c_int,
        x: *const T,
        incx: *const c_int,
        beta: *const T,
        y: *mut T,
        incy: *const c_int,
    ) {
        let t = transposed(letter(trans));
        let (m, n, lda, incx, incy) = (int(m), int(n), int(lda), int(incx), int(incy));
        xerbla(
            "gemv",
            first_bad(&[(t.is_some(), 1), (m >= 0, 2), (n >= 0, 3), (lda >= m.max(1), 6), (incx != 0, 8), (incy != 0, 11)]),
        );
        let t = t == Some(true);
        let (len_x, len_y) = if t { (m, n) } else { (n, m) };
        let a = op(view(a, m, n, lda), t);
        gemm(*alpha, a, vector(x, len_x, incx), *beta, vector_mut(y, len_y, incy));
    }
}

exported! {
    /// BLAS `?symv`: `y ← α A x + β y`, `A` symmetric in one triangle.
    dsymv_, ssymv_ (
        uplo: *const c_char,
        n: *const c_int,
        alpha: *const T,
        a: *const T,
        lda: *const c_int,
        x: *const T,
        incx: *const c_int,
        beta: *const T,
        y: *mut T,
        incy: *const c_int,
    ) {
        let up = upper(letter(uplo));
        let (n, lda, incx, incy) = (int(n), int(lda), int(incx), int(incy));
        xerbla("symv", first_bad(&[(up.is_some(), 1), (n >= 0, 2), (lda >= n.max(1), 5), (incx != 0, 7), (incy != 0, 10)]));
        symv(up == Some(true), *alpha, view(a, n, n, lda), vector(x, n, incx), *beta, vector_mut(y, n, incy));
    }
}

exported! {
    /// BLAS `?syrk`: one triangle of `C ← α op(A) op(A)ᵀ + β C`.
    dsyrk_, ssyrk_ (
        uplo: *const c_char,
        trans: *const c_char,
        n: *const c_int,
        k: *const c_int,
        alpha: *const T,
        a: *const T,
        lda: *const c_int,
        beta: *const T,
        c: *mut T,
        ldc: *const c_int,
    ) {
        let (up, t) = (upper(letter(uplo)), transposed(letter(trans)));
        let (n, k, lda, ldc) = (int(n), int(k), int(lda), int(ldc));
        let rows_a = if t == Some(true) { k } else { n };
        xerbla(
            "syrk",
            first_bad(&[
                (up.is_some(), 1),
                (t.is_some(), 2),
                (n >= 0, 3),
                (k >= 0, 4),
                (lda >= rows_a.max(1), 7),
                (ldc >= n.max(1), 10),
            ]),
        );
        let t = t == Some(true);
        let a = op(view(a, rows_a, if t { n } else { k }, lda), t);
        syrk(up == Some(true), *alpha, a, *beta, view_mut(c, n, n, ldc));
    }
}

exported! {
    /// BLAS `?syr2k`: one triangle of `C ← α (op(A) op(B)ᵀ + op(B) op(A)ᵀ) + β C`.
    dsyr2k_, ssyr2k_ (
        uplo: *const c_char,
        trans: *const c_char,
        n: *const c_int,
        k: *const c_int,
        alpha: *const T,
        a: *const T,
        lda: *const c_int,
        b: *const T,
        ldb: *const c_int,
        beta: *const T,
        c: *mut T,
        ldc: *const c_int,
    ) {
        let (up, t) = (upper(letter(uplo)), transposed(letter(trans)));
        let (n, k, lda, ldb, ldc) = (int(n), int(k), int(lda), int(ldb), int(ldc));
        let rows = if t == Some(true) { k } else { n };
        xerbla(
            "syr2k",
            first_bad(&[
                (up.is_some(), 1),
                (t.is_some(), 2),
                (n >= 0, 3),
                (k >= 0, 4),
                (lda >= rows.max(1), 7),
                (ldb >= rows.max(1), 9),
                (ldc >= n.max(1), 12),
            ]),
        );
        let t = t == Some(true);
        let cols = if t { n } else { k };
        let (a, b) = (op(view(a, rows, cols, lda), t), op(view(b, rows, cols, ldb), t));
        syr2k(up == Some(true), *alpha, a, b, *beta, view_mut(c, n, n, ldc));
    }
}
