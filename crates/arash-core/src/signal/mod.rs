//! Signal processing below identification, diagnosis and the flight log: what each of them
//! reads a log with. The resampling onto a uniform grid, an encoder's step, the zero-phase
//! Butterworth filter, the conditioning built on it (period averaging, central differences,
//! filtered columns), and the batch-means error that held-out comparisons are read with. The choices made from them (the period, the cut-off, the friction law)
//! still live in `identify` (issue 59 moves them here).

pub mod conditioning;
pub mod encoder;
pub mod filter;
pub mod resample;
pub mod statistics;
