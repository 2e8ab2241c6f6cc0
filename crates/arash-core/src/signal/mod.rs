//! The signal layer, below identification and the diagnosis: what each of them reads a log with,
//! and every choice made from a log before a model is fitted to it, each in one home.
//!
//! - Always (the daemon's flight log reads with them too): an encoder's step, resampling onto a
//!   uniform grid, and the batch-means error held-out comparisons are read with (`statistics`).
//! - With `identification`: the zero-phase Butterworth (`filter`), the conditioning built on it
//!   (period averaging, central differences, filtered columns), the preprocessing's settings
//!   (`options`), the log and the declared robot (`log`), the period, bandwidth and cut-off rule
//!   (`data_choices`), the friction velocity (`friction`), a log's repair and resting samples,
//!   the pipeline (`preprocess`), the least squares every choice is judged by and its metrics
//!   (`estimate`), each joint's Coulomb law (`friction_law`) and the cut-off chosen by held-out
//!   fit (`cutoff`).

pub mod encoder;
pub mod resample;
pub mod statistics;

// The filter's design is sci-rs's, which the rig's binary does not link (it filters nothing).
#[cfg(feature = "identification")]
pub mod conditioning;
#[cfg(feature = "identification")]
pub mod filter;

#[cfg(feature = "identification")]
pub mod cutoff;
#[cfg(feature = "identification")]
pub mod data_choices;
#[cfg(feature = "identification")]
pub mod estimate;
#[cfg(feature = "identification")]
pub mod friction;
#[cfg(feature = "identification")]
pub mod friction_law;
#[cfg(feature = "identification")]
pub mod log;
#[cfg(feature = "identification")]
pub mod options;
#[cfg(feature = "identification")]
pub mod preprocess;
#[cfg(feature = "identification")]
pub mod repair;
#[cfg(feature = "identification")]
pub mod resting;
