//! How the daemon turns drive units (encoder counts, motor amperes) into joint units (rad or m,
//! N·m or N). The mock motor uses the same conversion, so the two always agree.

use arash_core::sim::scenario::Sensors;

/// Joint torque per ampere of motor current: a 27.6 mN·m/A motor behind the 12:1 cable
/// reductions of φ and ψ, and behind the 2.5 mm insertion capstan.
pub const DEFAULT_TORQUE_CONSTANT: [f64; 3] = [0.0276 * 12.0, 0.0276 * 12.0, 0.0276 / 0.0025];

/// Per-joint conversion between drive and joint units (the `[drive]` table of the daemon's
/// configuration).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DriveConfig {
    /// Encoder counts per motor revolution (after quadrature).
    pub counts_per_rev: Vec<f64>,
    /// Joint motion per motor radian (rad/rad, or m/rad for the insertion capstan).
    pub transmission: Vec<f64>,
    /// Joint torque per ampere (N·m/A, or N/A for insertion).
    pub torque_constant: Vec<f64>,
}

impl Default for DriveConfig {
    fn default() -> Self {
        let s = Sensors::default();
        Self {
            counts_per_rev: s.counts_per_rev,
            transmission: s.transmission,
            torque_constant: DEFAULT_TORQUE_CONSTANT.to_vec(),
        }
    }
}

impl DriveConfig {
    /// Joint motion per encoder count.
    pub fn resolution(&self, joint: usize) -> f64 {
        2.0 * std::f64::consts::PI * self.transmission[joint] / self.counts_per_rev[joint]
    }

    /// Checks lengths and signs; the error names the key (`drive.<name>`).
    pub fn validate(&self, dof: usize) -> Result<(), DriveConfigError> {
        for (name, v) in [
            ("counts_per_rev", &self.counts_per_rev),
            ("transmission", &self.transmission),
            ("torque_constant", &self.torque_constant),
        ] {
            if v.len() != dof {
                return Err(DriveConfigError::Length { name, got: v.len(), dof });
            }
            if let Some((k, x)) = v.iter().enumerate().find(|(_, x)| !(x.is_finite() && **x > 0.0)) {
                return Err(DriveConfigError::NotPositive { name, joint: k, value: *x });
            }
        }
        Ok(())
    }
}

/// A [`DriveConfig`] that does not fit the robot, named by its key.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DriveConfigError {
    #[error("drive.{name} has {got} entries; the robot has {dof} joints")]
    Length { name: &'static str, got: usize, dof: usize },
    #[error("drive.{name}[{joint}] must be positive and finite, not {value}")]
    NotPositive { name: &'static str, joint: usize, value: f64 },
}
