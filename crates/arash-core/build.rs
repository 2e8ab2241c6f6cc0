//! Clarabel's PSD cone calls BLAS and LAPACK through `blas-sys`/`lapack-sys`, which leave linking
//! to the final crate. We link the system's reference libraries (Debian: liblapack-dev,
//! libblas-dev) rather than building OpenBLAS or netlib from source, which needs network access or
//! gfortran and minutes of compile time.
fn main() {
    println!("cargo:rustc-link-lib=dylib=lapack");
    println!("cargo:rustc-link-lib=dylib=blas");
}
