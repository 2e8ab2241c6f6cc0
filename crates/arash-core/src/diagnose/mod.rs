//! Closing the loop on measured data: find what the declared model leaves in the residual, name
//! the effect it comes from, add it, and report the error before and after (`docs/diagnosis.md`).
//!
//! The search is forward selection over the [`crate::effects`] with a decision rule built for robot
//! residuals, which are correlated over seconds:
//!
//! 1. a time misalignment is searched first, as an integer shift of the torque, because an
//!    unmodelled delay otherwise masquerades as velocity-dependent friction;
//! 2. each candidate group is partialled against the current model and gated by a batch Wald test
//!    whose batches are as long as its own scores' correlation asks ([`regression::test_group`]);
//! 3. candidates the current model already explains (VIF above the limit) are not identifiable
//!    and are set aside with that reason;
//! 4. Holm's procedure corrects for the number of candidates tested in the round;
//! 5. the survivors are ranked by how much they cut the error on held-out data (a validation log,
//!    or the odd-numbered blocks when fitting on the even ones), and one that does not cut it by
//!    at least `min_gain` is not worth a term;
//! 6. the best is added, the model refitted, and the search repeated until nothing passes;
//! 7. no joint is left predicting the held-out data worse than the model the search started
//!    from: a refitted friction goes back to the given model's, an effect that harms a joint
//!    beyond the comparison's noise is dropped (`diagnose/guard.rs`).
//!
//! Against a given model every test also counts that model's own calibration error: its held
//! parameters' covariance and, on torque computed from currents, its drive gains'
//! (`diagnose/calibration_error.rs`, `diagnose/gain_share.rs`).

mod band;
mod band_choice;
mod calibration_error;
mod candidates;
mod delay;
mod findings;
mod gain_share;
mod guard;
mod inputs;
mod noise;
mod options;
mod outcome;
mod prepare;
mod refit;
pub mod regression;
mod report;
mod search;
mod start;
mod weighted_fit;

pub use crate::effects::{EffectKind, EffectTerm, TermState};
pub use crate::signal::log::{Declared, Log};
pub use delay::ALIGNMENT_SAMPLES;
pub use findings::{
    DiagnoseSettings, Diagnosis, ErrorSummary, Finding, Rejection, RejectionReason, Reversion, Reverted,
    ScaleRefinement, Series, StartedFrom, Worse,
};
pub use options::{DiagnoseError, DiagnoseOptions, OptionsError, Start};
pub use refit::consistent_with_effects;
pub use start::diagnose;

/// Held-out data: one log, or several runs recorded one after another and concatenated, with
/// `starts` the sample at which each run after the first begins. The log is filtered whole, and
/// the samples within the filter's start-up transient of each start are left out, as at its
/// ends: across a start the position and torque jump (the robot moved between the runs).
#[derive(Debug, Clone, Copy)]
pub struct Runs<'a> {
    pub log: Log<'a>,
    pub starts: &'a [usize],
}

impl Runs<'_> {
    /// The starts increase strictly and lie inside the log, after its first sample.
    pub fn check(&self) -> Result<(), DiagnoseError> {
        let samples = self.log.t.len();
        let starts = self.starts;
        if starts.first() == Some(&0) || starts.windows(2).any(|w| w[1] <= w[0]) || starts.last() >= Some(&samples) {
            return Err(DiagnoseError::RunStarts { starts: starts.to_vec(), samples });
        }
        Ok(())
    }
}

impl<'a> From<Log<'a>> for Runs<'a> {
    fn from(log: Log<'a>) -> Self {
        Self { log, starts: &[] }
    }
}
