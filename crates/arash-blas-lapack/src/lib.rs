//! `arash-blas-lapack`: the BLAS and LAPACK routines Clarabel's semidefinite cone calls, written on
//! faer, so that arash needs no system BLAS or LAPACK (docs/architecture.md, "BLAS and LAPACK").
//!
//! A crate of its own so that only what runs the SDP links it: arash-core's `blas-lapack`
//! feature (on by default, with `identification`) pulls it in; the rig never does, and a binary
//! with a BLAS of its own turns the feature off.
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
