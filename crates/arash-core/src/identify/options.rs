//! Identification's settings, each with its `Default` (the one home of its defaults) and a
//! `validate` that names the setting it refuses: [`PreprocessOptions`], [`ConsistentOptions`] and
//! [`ExcitationOptions`]. The CLI, the Python bindings and the diagnosis start from `Default` and
//! override only what their user set; the functions that take them validate them first, so a bad
//! setting is refused by name before any work starts, from any front end.

use crate::base_parameters::DEFAULT_POSITION_MARGIN;

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
fn positive(name: &'static str, value: f64) -> Result<(), SettingError> {
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

/// Settings for [`identify_consistent`](super::consistent::identify_consistent): the physically
/// consistent fit's semidefinite problem.
#[derive(Clone, Debug)]
pub struct ConsistentOptions {
    /// Strength of the pull toward CAD, relative to the data (0 disables it).
    pub pull: f64,
    /// Bounds on each joint's cable stiffness `ke` (N·m/rad or N/m).
    pub stiffness_bounds: (f64, f64),
    /// Length scale ℓ used to scale first moments and inertias (m).
    pub length_scale: f64,
}

impl Default for ConsistentOptions {
    fn default() -> Self {
        Self {
            pull: 1e-4,
            stiffness_bounds: (0.0, f64::INFINITY),
            length_scale: crate::physical::DEFAULT_LENGTH_SCALE_M,
        }
    }
}

impl ConsistentOptions {
    /// Check every setting before the problem is built.
    pub fn validate(&self) -> Result<(), SettingError> {
        if !(self.pull.is_finite() && self.pull >= 0.0) {
            return Err(SettingError::new("pull", self.pull, "a non-negative number (0 disables the pull toward CAD)"));
        }
        let (lo, hi) = self.stiffness_bounds;
        if !(lo.is_finite() && lo >= 0.0 && !hi.is_nan() && hi >= lo) {
            return Err(SettingError::new(
                "stiffness_bounds",
                format!("({lo}, {hi})"),
                "0 ≤ lower ≤ upper, the lower finite (the upper may be infinite)",
            ));
        }
        positive("length_scale", self.length_scale)
    }
}

/// Settings for [`design_excitation`](super::excitation::design_excitation); `Default` is the paper's L = 5, T = 15 s.
#[derive(Clone, Debug)]
pub struct ExcitationOptions {
    pub harmonics: usize,
    pub period_s: f64,
    /// Seeded restarts of the optimiser.
    pub restarts: usize,
    pub seed: u64,
    /// Instants per period in the condition-number objective.
    pub samples: usize,
    /// Acceleration limit per joint (rad/s² or m/s²); `None` uses
    /// [`crate::base_parameters::DEFAULT_ACCELERATION_PER_SPEED`] × the speed limit.
    pub acceleration_limits: Option<Vec<f64>>,
    /// Fraction of each position range kept clear at both ends.
    pub margin: f64,
    /// Nelder–Mead iterations per restart.
    pub iterations: u64,
    /// Least share of each joint's usable position range the trajectory must cover.
    pub min_range_fraction: f64,
    /// Least peak speed of each joint, as a share of the fastest the series can move over that
    /// range (the speed limit, or ω·L times half the range when that is lower).
    pub min_speed_fraction: f64,
}

impl Default for ExcitationOptions {
    fn default() -> Self {
        Self {
            harmonics: 5,
            period_s: 15.0,
            restarts: 12,
            seed: 1,
            samples: 150,
            acceleration_limits: None,
            margin: DEFAULT_POSITION_MARGIN,
            iterations: 1000,
            min_range_fraction: 0.7,
            min_speed_fraction: 0.5,
        }
    }
}

impl ExcitationOptions {
    /// Check every setting that does not depend on the robot (the least number of `samples`
    /// does: twice the base parameters, checked by the design).
    pub fn validate(&self) -> Result<(), SettingError> {
        if self.harmonics < 2 {
            return Err(SettingError::new("harmonics", self.harmonics, "2 or more (to start and end at rest)"));
        }
        positive("period_s", self.period_s)?;
        for (name, value) in
            [("restarts", self.restarts as u64), ("samples", self.samples as u64), ("iterations", self.iterations)]
        {
            if value == 0 {
                return Err(SettingError::new(name, 0, "1 or more"));
            }
        }
        if !(self.margin.is_finite() && (0.0..0.5).contains(&self.margin)) {
            return Err(SettingError::new("margin", self.margin, "a share of each range from 0 to below 0.5"));
        }
        for (name, value) in
            [("min_range_fraction", self.min_range_fraction), ("min_speed_fraction", self.min_speed_fraction)]
        {
            if !(value.is_finite() && (0.0..=1.0).contains(&value)) {
                return Err(SettingError::new(name, value, "a share from 0 to 1"));
            }
        }
        for &a in self.acceleration_limits.iter().flatten() {
            positive("acceleration_limits", a)?;
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
        assert_eq!(ConsistentOptions::default().validate(), Ok(()));
        assert_eq!(ExcitationOptions::default().validate(), Ok(()));
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
        let con = ConsistentOptions::default;
        assert_eq!(name(ConsistentOptions { pull: -1e-4, ..con() }.validate()), "pull");
        assert_eq!(name(ConsistentOptions { pull: f64::INFINITY, ..con() }.validate()), "pull");
        assert_eq!(name(ConsistentOptions { stiffness_bounds: (2.0, 1.0), ..con() }.validate()), "stiffness_bounds");
        assert_eq!(name(ConsistentOptions { length_scale: 0.0, ..con() }.validate()), "length_scale");
        let exc = ExcitationOptions::default;
        assert_eq!(name(ExcitationOptions { harmonics: 1, ..exc() }.validate()), "harmonics");
        assert_eq!(name(ExcitationOptions { period_s: 0.0, ..exc() }.validate()), "period_s");
        assert_eq!(name(ExcitationOptions { restarts: 0, ..exc() }.validate()), "restarts");
        assert_eq!(name(ExcitationOptions { margin: 0.5, ..exc() }.validate()), "margin");
        assert_eq!(name(ExcitationOptions { min_speed_fraction: 1.5, ..exc() }.validate()), "min_speed_fraction");
        let bad_limit = ExcitationOptions { acceleration_limits: Some(vec![1.0, -1.0]), ..exc() };
        assert_eq!(name(bad_limit.validate()), "acceleration_limits");
    }

    #[test]
    fn the_message_says_what_is_expected() {
        let e = ConsistentOptions { pull: -1.0, ..Default::default() }.validate().unwrap_err();
        assert_eq!(
            e.to_string(),
            "pull = -1 cannot be used: expected a non-negative number (0 disables the pull toward CAD)"
        );
    }
}
