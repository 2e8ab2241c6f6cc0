//! The preprocessing's settings ([`PreprocessOptions`], with its `Default`: the one home of its
//! defaults) and the error every settings type refuses a value with ([`SettingError`]). The CLI,
//! the Python bindings, identification and the diagnosis start from `Default` and override only
//! what their user set; [`preprocess`](super::preprocess::preprocess) validates them first, so a
//! bad setting is refused by name before any work starts, from any front end.

/// A setting that cannot be used: its name, the value given and what it must be.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} = {value} cannot be used: expected {expected}")]
pub struct SettingError {
    pub name: &'static str,
    pub value: String,
    pub expected: String,
}

impl SettingError {
    pub fn new(name: &'static str, value: impl std::fmt::Display, expected: impl Into<String>) -> Self {
        Self { name, value: value.to_string(), expected: expected.into() }
    }
}

/// `value` if it is a positive, finite number.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<(), SettingError> {
    match value.is_finite() && value > 0.0 {
        true => Ok(()),
        false => Err(SettingError::new(name, value, "a positive number")),
    }
}

/// Settings for [`preprocess`](super::preprocess::preprocess): the one home of the preprocessing defaults, which every front end
/// (CLI, Python, diagnosis, demo) starts from, overriding only what its user set. `Default` leaves
/// the period and the cut-off to the data ([`super::data_choices`]) and keeps the paper's order 5.
#[derive(Clone, Debug, PartialEq)]
pub struct PreprocessOptions {
    /// Number of whole excitation periods in the log: `None` finds them from the data (and finds
    /// whether the log is periodic at all); `Some(1)` says it is not periodic (no averaging).
    pub periods: Option<usize>,
    /// The period (s), when known but not the number of periods: the log is averaged over as many
    /// whole periods as it holds. Takes precedence over `periods`.
    pub period_s: Option<f64>,
    /// Low-pass cut-off (Hz); `None` takes [`CUTOFF_PER_BANDWIDTH`](super::preprocess::CUTOFF_PER_BANDWIDTH) times the highest frequency
    /// of the motion, read from the positions' spectrum against their noise floor.
    pub cutoff_hz: Option<f64>,
    /// Butterworth order, applied forward and backward.
    pub order: usize,
    /// Keep every `decimate`-th sample after filtering (1 keeps all).
    pub decimate: usize,
    /// Cut-off of the velocity that switches Coulomb friction (Hz), at most a quarter of the
    /// sample rate; `None`: chosen by the fit ([`super::cutoff`]) in identification and the
    /// diagnosis, the main cut-off when preprocessing alone.
    pub friction_cutoff_hz: Option<f64>,
    /// Filter q̇ and q̈ again after each central difference (the paper's method). Off, the
    /// derivatives of the filtered position pass through the filter once, exactly as the torque
    /// does, which matters when the signals have content near the cut-off (the diagnosis).
    pub filter_derivatives: bool,
    /// Leave each joint's resting samples out of the fit ([`super::resting`]). The diagnosis, which
    /// builds and scores its own rows at every sample, turns it off.
    pub leave_out_rests: bool,
}

/// The highest Butterworth order accepted: beyond it a zero-phase pass rings more than it gains.
pub const MAX_ORDER: usize = 12;

impl Default for PreprocessOptions {
    fn default() -> Self {
        Self {
            periods: None,
            period_s: None,
            cutoff_hz: None,
            order: 5,
            decimate: 1,
            friction_cutoff_hz: None,
            filter_derivatives: true,
            leave_out_rests: true,
        }
    }
}

impl PreprocessOptions {
    /// Check every setting before any work starts.
    pub fn validate(&self) -> Result<(), SettingError> {
        for (name, value) in [
            ("cutoff_hz", self.cutoff_hz),
            ("friction_cutoff_hz", self.friction_cutoff_hz),
            ("period_s", self.period_s),
        ] {
            if let Some(v) = value {
                positive(name, v)?;
            }
        }
        if self.periods == Some(0) {
            return Err(SettingError::new("periods", 0, "1 (not periodic) or more"));
        }
        if !(1..=MAX_ORDER).contains(&self.order) {
            return Err(SettingError::new("order", self.order, format!("an order from 1 to {MAX_ORDER}")));
        }
        if self.decimate == 0 {
            return Err(SettingError::new("decimate", 0, "1 (keep every sample) or more"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_valid() {
        assert_eq!(PreprocessOptions::default().validate(), Ok(()));
    }

    #[test]
    fn each_bad_setting_is_named() {
        let name = |e: Result<(), SettingError>| e.unwrap_err().name;
        let pre = PreprocessOptions::default;
        assert_eq!(name(PreprocessOptions { cutoff_hz: Some(-1.0), ..pre() }.validate()), "cutoff_hz");
        assert_eq!(
            name(PreprocessOptions { friction_cutoff_hz: Some(f64::NAN), ..pre() }.validate()),
            "friction_cutoff_hz"
        );
        assert_eq!(name(PreprocessOptions { periods: Some(0), ..pre() }.validate()), "periods");
        assert_eq!(name(PreprocessOptions { order: MAX_ORDER + 1, ..pre() }.validate()), "order");
        assert_eq!(name(PreprocessOptions { decimate: 0, ..pre() }.validate()), "decimate");
    }
}
