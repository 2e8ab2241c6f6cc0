"""The BLAS and LAPACK routines arash provides to Clarabel (arash-core's `blas_lapack`, issue
20), called through their exported symbols with ctypes exactly as Clarabel calls them, against
scipy's LAPACK and BLAS (`scipy.linalg.lapack`, `scipy.linalg.blas`) as the reference, including
the edge cases Clarabel meets: a matrix that is not positive definite, NaN, the triangle LAPACK
leaves alone, workspace queries, strided storage."""

import ctypes
from ctypes import POINTER, byref, c_char, c_double, c_float, c_int

import numpy as np
import pytest
from scipy.linalg import blas, lapack

import arash._arash

LIB = ctypes.CDLL(arash._arash.__file__)
RNG = np.random.default_rng(20)
REAL = {np.float64: c_double, np.float32: c_float}


def ch(letter):
    return byref(c_char(letter.encode()))


def i(n):
    return byref(c_int(n))


def scalar(x, dtype):
    return byref(REAL[dtype](x))


def ptr(a):
    return a.ctypes.data_as(POINTER(REAL[a.dtype.type]))


def iptr(a):
    return a.ctypes.data_as(POINTER(c_int))


def padded(a, extra=2, fill=np.nan):
    """`a` stored column-major with a leading dimension `extra` rows larger, the padding NaN:
    a routine that reads outside the matrix would spread it."""
    m, n = a.shape
    store = np.full((m + extra, n), fill, dtype=a.dtype, order="F")
    store[:m] = a
    return store


def spd(n, dtype=np.float64):
    x = RNG.normal(size=(n, n))
    return (x @ x.T + n * np.eye(n)).astype(dtype)


def symmetric(n):
    x = RNG.normal(size=(n, n))
    return x + x.T


# ---- LAPACK --------------------------------------------------------------------------------------


def potrf(a, uplo):
    a = padded(a)
    info = c_int(-99)
    LIB.dpotrf_(ch(uplo), i(a.shape[1]), ptr(a), i(a.shape[0]), byref(info))
    return a[: a.shape[1]], info.value


@pytest.mark.parametrize("n", [1, 4, 9])
@pytest.mark.parametrize("uplo", ["U", "L"])
def test_potrf_matches_lapack_and_leaves_the_other_triangle_alone(n, uplo):
    a = spd(n)
    sentinel = a.copy()
    other = np.tril_indices(n, -1) if uplo == "U" else np.triu_indices(n, 1)
    sentinel[other] = 1234.5
    ours, info = potrf(sentinel, uplo)
    ref, ref_info = lapack.dpotrf(a, lower=uplo == "L", clean=False)
    assert info == ref_info == 0
    mine = np.triu_indices(n) if uplo == "U" else np.tril_indices(n)
    np.testing.assert_allclose(ours[mine], ref[mine], rtol=1e-12, atol=1e-12)
    assert np.all(ours[other] == 1234.5)


@pytest.mark.parametrize("uplo", ["U", "L"])
def test_potrf_reports_the_first_minor_that_is_not_positive_as_lapack_does(uplo):
    for k in (1, 3, 5):
        a = spd(6)
        # Make the leading k × k minor indefinite and nothing before it.
        a[k - 1, k - 1] = -abs(a[k - 1, k - 1]) - 50
        _, info = potrf(a, uplo)
        _, ref_info = lapack.dpotrf(a, lower=uplo == "L")
        assert info == ref_info == k


def netlib_lapack():
    """Debian's reference LAPACK when the machine has it (arash does not need it)."""
    try:
        return ctypes.CDLL("liblapack.so.3")
    except OSError:
        return None


def test_potrf_reports_nan_as_not_positive_definite():
    """Reference LAPACK stops at the first pivot that is not a positive number, NaN included
    (`dpotf2`: AJJ.LE.ZERO .OR. DISNAN(AJJ)); so does arash's, so that Clarabel sees a failed
    factorisation, not a factor full of NaN. scipy's OpenBLAS does not check for NaN (it returns
    0), so the reference here is the pivot where the NaN first reaches the diagonal, and Debian's
    reference LAPACK where installed."""
    netlib = netlib_lapack()
    for where, first_pivot in (((0, 0), 1), ((2, 2), 3), ((3, 1), 4)):
        a = spd(5)
        a[where] = a[where[::-1]] = np.nan
        for uplo in "UL":
            _, info = potrf(a, uplo)
            assert info == first_pivot
            if netlib is not None:
                b, ref_info = padded(a), c_int(-99)
                netlib.dpotrf_(ch(uplo), i(5), ptr(b), i(b.shape[0]), byref(ref_info))
                assert ref_info.value == first_pivot


@pytest.mark.parametrize("uplo", ["U", "L"])
def test_potrs_solves_with_the_factor(uplo):
    n, nrhs = 6, 3
    a = spd(n)
    factor, _ = potrf(a, uplo)
    b0 = RNG.normal(size=(n, nrhs))
    b = padded(b0)
    f = padded(factor)
    info = c_int(-99)
    LIB.dpotrs_(ch(uplo), i(n), i(nrhs), ptr(f), i(f.shape[0]), ptr(b), i(b.shape[0]), byref(info))
    ref, ref_info = lapack.dpotrs(np.asfortranarray(factor), b0, lower=uplo == "L")
    assert info.value == ref_info == 0
    np.testing.assert_allclose(b[:n], ref, rtol=1e-10)
    np.testing.assert_allclose(b[:n], np.linalg.solve(a, b0), rtol=1e-9)


def syevr(a, jobz, rng="A", uplo="U", vl=0.0, vu=0.0, il=1, iu=1, dtype=np.float64):
    n = a.shape[0]
    a = padded(a.astype(dtype))
    m, info = c_int(-1), c_int(-99)
    w = np.zeros(n, dtype=dtype)
    z = np.zeros((n, n) if jobz == "V" else (1, 1), dtype=dtype, order="F")
    isuppz = np.zeros(2 * n, dtype=np.int32)
    work, iwork = np.zeros(1, dtype=dtype), np.zeros(1, dtype=np.int32)
    routine = LIB.dsyevr_ if dtype == np.float64 else LIB.ssyevr_
    args = lambda lwork, liwork: (  # noqa: E731  (Clarabel's two calls: query, then solve)
        ch(jobz), ch(rng), ch(uplo), i(n), ptr(a), i(a.shape[0]), scalar(vl, dtype), scalar(vu, dtype), i(il), i(iu),
        scalar(-1.0, dtype), byref(m), ptr(w), ptr(z), i(max(n, 1)), iptr(isuppz), ptr(work), i(lwork), iptr(iwork),
        i(liwork), byref(info))
    routine(*args(-1, -1))
    assert info.value == 0 and work[0] >= 1 and iwork[0] >= 1
    work, iwork = np.zeros(int(work[0]), dtype=dtype), np.zeros(int(iwork[0]), dtype=np.int32)
    routine(*args(len(work), len(iwork)))
    return w[: m.value], z[:, : m.value], isuppz, info.value


@pytest.mark.parametrize("n", [4, 10])
@pytest.mark.parametrize("uplo", ["U", "L"])
def test_syevr_all_eigenpairs_match_lapack(n, uplo):
    a = symmetric(n)
    w, z, isuppz, info = syevr(a, "V", uplo=uplo)
    ref_w, ref_z, _, _, ref_info = lapack.dsyevr(a, compute_v=1, lower=uplo == "L")
    assert info == ref_info == 0
    np.testing.assert_allclose(w, ref_w, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(z * ref_z, axis=0)), 1.0, atol=1e-10)  # same vectors up to sign
    np.testing.assert_allclose(z.T @ z, np.eye(n), atol=1e-12)
    assert np.all(isuppz[0::2] >= 1) and np.all(isuppz[1::2] <= n)
    values, _, info = syevr(a, "N", uplo=uplo)[:3]
    np.testing.assert_allclose(values, ref_w, rtol=1e-12, atol=1e-12)


def test_syevr_reads_only_its_triangle():
    a = symmetric(5)
    w_up = syevr(np.triu(a) + np.tril(np.full((5, 5), 99.0), -1), "N", uplo="U")[0]
    w_low = syevr(np.tril(a) + np.triu(np.full((5, 5), -7.0), 1), "N", uplo="L")[0]
    ref = np.linalg.eigvalsh(a)
    np.testing.assert_allclose(w_up, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(w_low, ref, rtol=1e-12, atol=1e-12)


def test_syevr_ranges_by_value_and_index_match_lapack():
    a = symmetric(8)
    ref_all = np.linalg.eigvalsh(a)
    vl, vu = ref_all[2] - 1e-3, ref_all[5] + 1e-3
    w, z, _, info = syevr(a, "V", rng="V", vl=vl, vu=vu)
    ref_w, _, ref_m, _, _ = lapack.dsyevr(a, compute_v=1, range="V", vl=vl, vu=vu)
    assert info == 0 and len(w) == ref_m == 4
    np.testing.assert_allclose(w, ref_w[:ref_m], rtol=1e-12)
    np.testing.assert_allclose(a @ z, z * w, atol=1e-10)
    w, _, _, _ = syevr(a, "V", rng="I", il=2, iu=4)
    np.testing.assert_allclose(w, ref_all[1:4], rtol=1e-12)


def test_syevr_refuses_a_bad_argument_by_its_position():
    a = padded(symmetric(3))
    info = c_int(0)
    dummy = np.zeros(100)
    idummy = np.zeros(100, dtype=np.int32)
    m = c_int(0)
    LIB.dsyevr_(ch("X"), ch("A"), ch("U"), i(3), ptr(a), i(a.shape[0]), scalar(0, np.float64), scalar(0, np.float64),
                i(1), i(1), scalar(-1, np.float64), byref(m), ptr(dummy), ptr(dummy), i(3), iptr(idummy), ptr(dummy),
                i(100), iptr(idummy), i(100), byref(info))
    assert info.value == -1


def test_the_single_precision_twins_agree():
    a = symmetric(6)
    w, _, _, info = syevr(a, "V", dtype=np.float32)
    assert info == 0
    np.testing.assert_allclose(w, lapack.ssyevr(a.astype(np.float32))[0], rtol=1e-4, atol=1e-4)
    b = spd(5, np.float32)
    f = padded(b)
    info = c_int(-99)
    LIB.spotrf_(ch("L"), i(5), ptr(f), i(f.shape[0]), byref(info))
    ref, ref_info = lapack.spotrf(b, lower=True)
    assert info.value == ref_info == 0
    np.testing.assert_allclose(np.tril(f[:5]), np.tril(ref), rtol=1e-5, atol=1e-5)


def svd(a, routine, job):
    m, n = a.shape
    k = min(m, n)
    store = padded(a)
    u_cols = m if job == "A" else k
    vt_rows = n if job == "A" else k
    u = np.full((m, u_cols), np.nan, order="F")
    vt = np.full((vt_rows, n), np.nan, order="F")
    s = np.zeros(k)
    work = np.zeros(1)
    iwork = np.zeros(8 * k, dtype=np.int32)
    info = c_int(-99)
    for lwork in (-1, None):
        lwork = lwork if lwork is not None else len(work)
        if routine == "gesdd":
            LIB.dgesdd_(ch(job), i(m), i(n), ptr(store), i(store.shape[0]), ptr(s), ptr(u), i(m), ptr(vt),
                        i(max(vt_rows, 1)), ptr(work), i(lwork), iptr(iwork), byref(info))
        else:
            LIB.dgesvd_(ch(job), ch(job), i(m), i(n), ptr(store), i(store.shape[0]), ptr(s), ptr(u), i(m), ptr(vt),
                        i(max(vt_rows, 1)), ptr(work), i(lwork), byref(info))
        assert info.value == 0
        if lwork == -1:
            work = np.zeros(max(int(work[0]), 1))
    return s, u, vt, store[:m]


@pytest.mark.parametrize("routine", ["gesdd", "gesvd"])
@pytest.mark.parametrize("shape", [(6, 4), (4, 6), (5, 5)])
@pytest.mark.parametrize("job", ["S", "A", "N"])
def test_svd_matches_lapack(routine, shape, job):
    a = RNG.normal(size=shape)
    s, u, vt, _ = svd(a, routine, job)
    ref_s = (lapack.dgesdd if routine == "gesdd" else lapack.dgesvd)(a, compute_uv=0)[1]
    np.testing.assert_allclose(s, ref_s, rtol=1e-12)
    if job != "N":
        k = min(shape)
        np.testing.assert_allclose(u[:, :k] * s @ vt[:k], a, atol=1e-12)
        np.testing.assert_allclose(u.T @ u, np.eye(u.shape[1]), atol=1e-12)
        np.testing.assert_allclose(vt @ vt.T, np.eye(vt.shape[0]), atol=1e-12)


def test_gesdd_overwrite_puts_the_factor_in_a():
    for shape in ((6, 4), (4, 6)):
        a = RNG.normal(size=shape)
        m, n = shape
        k = min(shape)
        store = padded(a)
        s = np.zeros(k)
        u = np.zeros((m, m), order="F")
        vt = np.zeros((n, n), order="F")
        work, iwork, info = np.zeros(10), np.zeros(8 * k, dtype=np.int32), c_int(-99)
        LIB.dgesdd_(ch("O"), i(m), i(n), ptr(store), i(store.shape[0]), ptr(s), ptr(u), i(m), ptr(vt), i(n),
                    ptr(work), i(10), iptr(iwork), byref(info))
        assert info.value == 0
        left, right = (store[:m, :k], vt[:k]) if m >= n else (u[:, :k], store[:k, :n])
        np.testing.assert_allclose(left * s @ right, a, atol=1e-12)


def test_gesv_matches_lapack_and_reports_a_singular_matrix():
    n, nrhs = 7, 2
    a = RNG.normal(size=(n, n))
    b = RNG.normal(size=(n, nrhs))
    store, rhs = padded(a), padded(b)
    ipiv, info = np.zeros(n, dtype=np.int32), c_int(-99)
    LIB.dgesv_(i(n), i(nrhs), ptr(store), i(store.shape[0]), iptr(ipiv), ptr(rhs), i(rhs.shape[0]), byref(info))
    lu, piv, x, ref_info = lapack.dgesv(a, b)
    assert info.value == ref_info == 0
    np.testing.assert_allclose(rhs[:n], x, rtol=1e-10)
    np.testing.assert_array_equal(ipiv - 1, piv)  # scipy reports the pivots 0-based
    np.testing.assert_allclose(store[:n], lu, rtol=1e-10, atol=1e-12)
    # A zero column stays exactly zero through elimination, whatever the order of operations, so
    # its pivot is exactly zero in both (a repeated column's would be rounding noise).
    singular = a.copy()
    singular[:, 5] = 0.0
    store = padded(singular)
    LIB.dgesv_(i(n), i(nrhs), ptr(store), i(store.shape[0]), iptr(ipiv), ptr(padded(b)), i(n + 2), byref(info))
    assert info.value == lapack.dgesv(singular, b)[3] == 6


# ---- BLAS ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("ta", ["N", "T"])
@pytest.mark.parametrize("tb", ["N", "T"])
@pytest.mark.parametrize("beta", [0.0, 0.5])
def test_gemm_matches_blas_and_a_zero_beta_never_reads_c(ta, tb, beta):
    m, n, k = 5, 4, 3
    a = RNG.normal(size=(m, k) if ta == "N" else (k, m))
    b = RNG.normal(size=(k, n) if tb == "N" else (n, k))
    c0 = RNG.normal(size=(m, n))
    c = padded(np.full((m, n), np.nan) if beta == 0 else c0)
    sa, sb = padded(a), padded(b)
    LIB.dgemm_(ch(ta), ch(tb), i(m), i(n), i(k), scalar(1.5, np.float64), ptr(sa), i(sa.shape[0]), ptr(sb),
               i(sb.shape[0]), scalar(beta, np.float64), ptr(c), i(c.shape[0]))
    ref = blas.dgemm(1.5, a, b, beta=beta, c=c0, trans_a=ta == "T", trans_b=tb == "T")
    np.testing.assert_allclose(c[:m], ref, rtol=1e-12)
    assert np.all(np.isnan(c[m:]))  # the padding is untouched


@pytest.mark.parametrize("trans", ["N", "T"])
@pytest.mark.parametrize("incx, incy", [(1, 1), (2, -1), (-3, 2)])
def test_gemv_with_strides_matches_blas(trans, incx, incy):
    m, n = 5, 3
    a = RNG.normal(size=(m, n))
    lx, ly = (n, m) if trans == "N" else (m, n)
    x = RNG.normal(size=abs(incx) * (lx - 1) + 1)
    y = RNG.normal(size=abs(incy) * (ly - 1) + 1)
    ours = y.copy()
    sa = padded(a)
    LIB.dgemv_(ch(trans), i(m), i(n), scalar(0.7, np.float64), ptr(sa), i(sa.shape[0]), ptr(x), i(incx),
               scalar(-0.3, np.float64), ptr(ours), i(incy))
    logical = lambda v, inc, length: v[::inc][:length] if inc > 0 else v[::inc][:length]  # noqa: E731
    xv, yv = logical(x, incx, lx), logical(y, incy, ly)
    expect = 0.7 * (a.T if trans == "T" else a) @ xv - 0.3 * yv
    got = logical(ours, incy, ly)
    np.testing.assert_allclose(got, expect, rtol=1e-12)
    ref = blas.dgemv(0.7, a, xv, beta=-0.3, y=yv.copy(), trans=int(trans == "T"))
    np.testing.assert_allclose(got, ref, rtol=1e-12)


@pytest.mark.parametrize("uplo", ["U", "L"])
def test_symv_reads_one_triangle(uplo):
    n = 6
    a = symmetric(n)
    stored = np.triu(a) if uplo == "U" else np.tril(a)
    stored[np.tril_indices(n, -1) if uplo == "U" else np.triu_indices(n, 1)] = np.nan
    x, y = RNG.normal(size=n), RNG.normal(size=n)
    ours = y.copy()
    sa = padded(stored)
    LIB.dsymv_(ch(uplo), i(n), scalar(2.0, np.float64), ptr(sa), i(sa.shape[0]), ptr(x), i(1),
               scalar(0.25, np.float64), ptr(ours), i(1))
    ref = blas.dsymv(2.0, a, x, beta=0.25, y=y.copy(), lower=int(uplo == "L"))
    np.testing.assert_allclose(ours, ref, rtol=1e-12)


@pytest.mark.parametrize("uplo", ["U", "L"])
@pytest.mark.parametrize("trans", ["N", "T"])
@pytest.mark.parametrize("two", [False, True])
def test_syrk_and_syr2k_update_one_triangle(uplo, trans, two):
    n, k = 5, 3
    a = RNG.normal(size=(n, k) if trans == "N" else (k, n))
    b = RNG.normal(size=a.shape)
    c0 = symmetric(n)
    c = padded(c0)
    other = np.tril_indices(n, -1) if uplo == "U" else np.triu_indices(n, 1)
    c[:n][other] = 77.0
    sa, sb = padded(a), padded(b)
    if two:
        LIB.dsyr2k_(ch(uplo), ch(trans), i(n), i(k), scalar(1.3, np.float64), ptr(sa), i(sa.shape[0]), ptr(sb),
                    i(sb.shape[0]), scalar(0.4, np.float64), ptr(c), i(c.shape[0]))
        ref = blas.dsyr2k(1.3, a, b, beta=0.4, c=c0, trans=int(trans == "T"), lower=int(uplo == "L"))
    else:
        LIB.dsyrk_(ch(uplo), ch(trans), i(n), i(k), scalar(1.3, np.float64), ptr(sa), i(sa.shape[0]),
                   scalar(0.4, np.float64), ptr(c), i(c.shape[0]))
        ref = blas.dsyrk(1.3, a, beta=0.4, c=c0, trans=int(trans == "T"), lower=int(uplo == "L"))
    mine = np.triu_indices(n) if uplo == "U" else np.tril_indices(n)
    np.testing.assert_allclose(c[:n][mine], ref[mine], rtol=1e-12)
    assert np.all(c[:n][other] == 77.0)
