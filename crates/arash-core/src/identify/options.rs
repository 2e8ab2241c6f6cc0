//! The excitation design's settings ([`ExcitationOptions`], with its `Default`: the one home of
//! its defaults, and a `validate` that names the setting it refuses). The preprocessing's are in
//! [`crate::signal::options`], the consistent fit's in [`crate::consistent`].

use crate::base_parameters::DEFAULT_POSITION_MARGIN;
use crate::signal::options::{positive, SettingError};

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
        assert_eq!(ExcitationOptions::default().validate(), Ok(()));
    }

    #[test]
    fn each_bad_setting_is_named() {
        let name = |e: Result<(), SettingError>| e.unwrap_err().name;
        let exc = ExcitationOptions::default;
        assert_eq!(name(ExcitationOptions { harmonics: 1, ..exc() }.validate()), "harmonics");
        assert_eq!(name(ExcitationOptions { period_s: 0.0, ..exc() }.validate()), "period_s");
        assert_eq!(name(ExcitationOptions { restarts: 0, ..exc() }.validate()), "restarts");
        assert_eq!(name(ExcitationOptions { margin: 0.5, ..exc() }.validate()), "margin");
        assert_eq!(name(ExcitationOptions { min_speed_fraction: 1.5, ..exc() }.validate()), "min_speed_fraction");
        let bad_limit = ExcitationOptions { acceleration_limits: Some(vec![1.0, -1.0]), ..exc() };
        assert_eq!(name(bad_limit.validate()), "acceleration_limits");
    }
}
