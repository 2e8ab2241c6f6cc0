//! A downstream program that links a BLAS of its own — here one routine, `dgemm_`, as OpenBLAS
//! or MKL would export it — beside everything the rig runs (arash-daemon, and with it
//! arash-core's model, control laws and flight log). The rig must not bring a second `dgemm_`:
//! arash's own BLAS and LAPACK live in the arash-blas-lapack crate, which only the SDP's users
//! link. This program building at all is the check (the workspace build links it); its test checks
//! that the symbol the program calls is its own.
//!
//! Had the rig linked arash-blas-lapack (or arash-core's identification with it), the link would
//! fail with "multiple definition of `dgemm_`".

use std::ffi::{c_char, c_int};

/// C = α·A·B + β·C for column-major A (m × k), B (k × n), no transposes: the one case this
/// program's callers need. The reference BLAS calling convention (every argument by pointer).
///
/// # Safety
/// The pointers must be valid for the sizes given, as for any BLAS.
#[no_mangle]
pub unsafe extern "C" fn dgemm_(
    _transa: *const c_char,
    _transb: *const c_char,
    m: *const c_int,
    n: *const c_int,
    k: *const c_int,
    alpha: *const f64,
    a: *const f64,
    lda: *const c_int,
    b: *const f64,
    ldb: *const c_int,
    beta: *const f64,
    c: *mut f64,
    ldc: *const c_int,
) {
    let (m, n, k) = (*m as usize, *n as usize, *k as usize);
    let (lda, ldb, ldc) = (*lda as usize, *ldb as usize, *ldc as usize);
    for j in 0..n {
        for i in 0..m {
            let dot: f64 = (0..k).map(|l| *a.add(i + l * lda) * *b.add(l + j * ldb)).sum();
            let out = c.add(i + j * ldc);
            *out = *alpha * dot + *beta * *out;
        }
    }
}

fn main() -> std::process::ExitCode {
    // The rig's entry points, held so that the linker keeps all of the rig beside `dgemm_`.
    let rig: [*const (); 2] =
        [arash_daemon::daemon::run as *const (), arash_daemon::daemon::startup::options as *const ()];
    std::hint::black_box(rig);
    std::process::ExitCode::SUCCESS
}

#[cfg(test)]
mod tests {
    use std::ffi::c_char;

    extern "C" {
        #[link_name = "dgemm_"]
        fn linked_dgemm(
            transa: *const c_char,
            transb: *const c_char,
            m: *const i32,
            n: *const i32,
            k: *const i32,
            alpha: *const f64,
            a: *const f64,
            lda: *const i32,
            b: *const f64,
            ldb: *const i32,
            beta: *const f64,
            c: *mut f64,
            ldc: *const i32,
        );
    }

    /// The `dgemm_` the link resolved is this program's: 2 × 2 products by hand.
    #[test]
    fn the_linked_dgemm_is_the_programs_own() {
        std::hint::black_box(arash_daemon::daemon::run as *const ());
        let (a, b) = ([1.0, 3.0, 2.0, 4.0], [5.0, 7.0, 6.0, 8.0]); // column-major [[1,2],[3,4]], [[5,6],[7,8]]
        let mut c = [1.0; 4];
        let (two, n) = (2, b'N' as c_char);
        unsafe {
            linked_dgemm(&n, &n, &two, &two, &two, &2.0, a.as_ptr(), &two, b.as_ptr(), &two, &0.5, c.as_mut_ptr(), &two)
        };
        // 2·A·B + 0.5: A·B = [[19, 22], [43, 50]].
        assert_eq!(c, [38.5, 86.5, 44.5, 100.5]);
    }
}
