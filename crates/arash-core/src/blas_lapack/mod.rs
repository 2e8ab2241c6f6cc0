//! The BLAS and LAPACK routines Clarabel's semidefinite cone calls, written on faer, so that
//! arash needs no system BLAS or LAPACK (docs/architecture.md, "BLAS and LAPACK").
//!
//! Clarabel reaches these through the `blas`/`lapack` crates, which declare the Fortran
//! symbols (`dsyevr_`, ...) and leave it to the final link to provide them; `blas-src` and
//! `lapack-src` without a backend provide nothing. Here they are, with the reference
//! implementations' calling convention (every argument by pointer, no hidden string lengths, as
//! `lapack-sys` 0.14 declares them), for both precisions: `?gemm ?gemv ?symv ?syrk ?syr2k` and
//! `?potrf ?potrs ?syevr ?gesdd ?gesvd ?gesv`. Nothing else in Clarabel 0.11 calls BLAS or LAPACK;
//! a routine missing here would fail the link, not the solve.
//!
//! Cones of size 3 or less never call them (Clarabel solves those in closed form); ARASH's 4 × 4
//! pseudo-inertia cones do, every iteration.

pub mod args;
pub mod blas;
pub mod lapack;

/// The addresses of the entry points, for a caller of Clarabel to hold: a linker that reads
/// each library once (GNU ld) then keeps them even though Clarabel, which needs them, comes
/// after arash-core on its command line.
pub fn entry_points() -> [*const (); 22] {
    use blas::*;
    use lapack::*;
    [
        dgemm_ as *const (),
        dgemv_ as *const (),
        dsymv_ as *const (),
        dsyrk_ as *const (),
        dsyr2k_ as *const (),
        dpotrf_ as *const (),
        dpotrs_ as *const (),
        dsyevr_ as *const (),
        dgesdd_ as *const (),
        dgesvd_ as *const (),
        dgesv_ as *const (),
        sgemm_ as *const (),
        sgemv_ as *const (),
        ssymv_ as *const (),
        ssyrk_ as *const (),
        ssyr2k_ as *const (),
        spotrf_ as *const (),
        spotrs_ as *const (),
        ssyevr_ as *const (),
        sgesdd_ as *const (),
        sgesvd_ as *const (),
        sgesv_ as *const (),
    ]
}
