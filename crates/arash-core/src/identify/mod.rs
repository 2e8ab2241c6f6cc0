//! Identification (paper sections III–IV): excitation design, preprocessing, least squares, and
//! physically consistent estimation.

pub mod consistent;
pub mod estimate;
pub mod filter;
pub mod preprocess;
