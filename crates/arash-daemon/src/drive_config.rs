//! How the daemon turns drive units (encoder counts, motor amperes) into joint units (rad or m,
//! N·m or N). The mock motor uses the same conversion, so the two always agree.

use arash_core::model_file::DriveGains;

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
        Self {
            counts_per_rev: arash_core::ARASH_ASIST_COUNTS_PER_REV.to_vec(),
            transmission: arash_core::ARASH_ASIST_TRANSMISSION.to_vec(),
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

/// How far a model's identified gain may be from `drive.torque_constant` before the daemon refuses
/// it: a datasheet is good to ±10 %, so a factor of two is a wrong current scale, a sign, or a
/// model of another rig, and taking it would scale every commanded current by as much.
pub const MAX_GAIN_RATIO: f64 = 2.0;

/// The torque per ampere the daemon uses on each joint, and where each came from.
#[derive(Clone, Debug, PartialEq)]
pub struct TorqueConstants {
    pub values: Vec<f64>,
    pub sources: Vec<String>,
}

impl TorqueConstants {
    /// Each joint's: the model's drive gain, identified with a known load (`arash identify
    /// --loaded --load`) or taken from a datasheet it records, where the model has one that the
    /// load fixed; otherwise `drive.torque_constant`. A model gain more than [`MAX_GAIN_RATIO`]
    /// from the configured one is refused.
    pub fn choose(
        drive: &DriveConfig,
        gains: Option<&DriveGains>,
        joints: &[String],
    ) -> Result<Self, DriveConfigError> {
        let configured = |j: usize, why: &str| (drive.torque_constant[j], format!("drive.torque_constant{why}"));
        let (values, sources) = (0..joints.len())
            .map(|j| {
                let Some(g) = gains else { return Ok(configured(j, "")) };
                let usable =
                    g.fixed.get(j).copied().unwrap_or(false) || g.from_datasheet.get(j).copied().unwrap_or(false);
                if !usable {
                    return Ok(configured(j, " (the model's load did not fix this gain)"));
                }
                let (k, c) = (g.gains[j], drive.torque_constant[j]);
                // Also refuses a negative gain, which would push every joint the wrong way.
                if !(k / c <= MAX_GAIN_RATIO && k / c >= 1.0 / MAX_GAIN_RATIO) {
                    return Err(DriveConfigError::GainFarFromConfig {
                        joint: joints[j].clone(),
                        model: k,
                        configured: c,
                    });
                }
                let source = match g.from_datasheet.get(j).copied().unwrap_or(false) {
                    true => format!("the model's, from a datasheet (± {:.2} %)", 100.0 * g.sigma[j] / k.abs()),
                    false => format!(
                        "the model's, identified with a {} kg load on {} (± {:.2} %)",
                        g.load_mass,
                        g.load_body,
                        100.0 * g.sigma[j] / k.abs()
                    ),
                };
                Ok((k, source))
            })
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .unzip();
        Ok(Self { values, sources })
    }
}

/// A [`DriveConfig`] that does not fit the robot, named by its key.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DriveConfigError {
    #[error("drive.{name} has {got} entries; the robot has {dof} joints")]
    Length { name: &'static str, got: usize, dof: usize },
    #[error("drive.{name}[{joint}] must be positive and finite, not {value}")]
    NotPositive { name: &'static str, joint: usize, value: f64 },
    #[error(
        "the model's drive gain of {joint} is {model:.4}, more than {MAX_GAIN_RATIO}× from drive.torque_constant \
         {configured:.4}: check the current's scale and sign, and that the model is this rig's; if the datasheet is \
         wrong, set drive.torque_constant near the identified gain"
    )]
    GainFarFromConfig { joint: String, model: f64, configured: f64 },
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gains(values: [f64; 3], fixed: [bool; 3], from_datasheet: [bool; 3]) -> DriveGains {
        DriveGains {
            gains: values.to_vec(),
            sigma: vec![0.01; 3],
            estimator: Default::default(),
            covariance: vec![],
            beta_per_gain: vec![],
            from_datasheet: from_datasheet.to_vec(),
            load_body: "insertion_carriage".into(),
            load_mass: 0.3,
            load_estimate: vec![],
            condition_number: 1.0,
            load_share: vec![0.1; 3],
            load_over_unexplained: vec![50.0; 3],
            fixed: fixed.to_vec(),
        }
    }

    /// A gain the load fixed, or a datasheet's the model records, is the model's; one the load
    /// did not fix stays the configuration's; one beyond the factor refuses, naming the joint.
    #[test]
    fn each_joint_takes_the_models_gain_only_where_it_is_known() {
        let drive = DriveConfig { torque_constant: vec![1.0, 1.0, 1.0], ..DriveConfig::default() };
        let joints: Vec<String> = ["yaw", "pitch", "insertion"].map(String::from).to_vec();
        let g = gains([1.1, 0.9, 1.5], [true, false, false], [false, true, false]);
        let chosen = TorqueConstants::choose(&drive, Some(&g), &joints).unwrap();
        assert_eq!(chosen.values, [1.1, 0.9, 1.0]);
        assert!(chosen.sources[0].contains("identified with a 0.3 kg load"), "{:?}", chosen.sources);
        assert!(chosen.sources[1].contains("from a datasheet") && chosen.sources[2].contains("did not fix"));
        assert_eq!(TorqueConstants::choose(&drive, None, &joints).unwrap().values, [1.0, 1.0, 1.0]);
        for far in [2.5, 0.3, -1.0] {
            let g = gains([1.0, far, 1.0], [true; 3], [false; 3]);
            let error = TorqueConstants::choose(&drive, Some(&g), &joints).unwrap_err().to_string();
            assert!(error.contains("pitch") && error.contains("more than 2×"), "{error}");
        }
    }
}
