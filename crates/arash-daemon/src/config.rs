//! The daemon's configuration file (TOML). Every table and key is optional; unknown keys are
//! errors that name the key, and values are checked with messages that name it too. Units are
//! SI (rad, m, N·m, N, s) unless the key says otherwise (`_ms`, `_hz`, `_mib`).

use std::path::{Path, PathBuf};

use arash_core::control::SafetyLimits;
use arash_core::Model;

use crate::drive_config::DriveConfig;
use crate::logger::LogConfig;
use crate::rt::clock::RtPolicy;

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DaemonConfig {
    /// The robot's URDF; default: the bundled ARASH:ASiST.
    pub robot: Option<PathBuf>,
    pub link: LinkConfig,
    pub drive: DriveConfig,
    pub control: ControlConfig,
    pub safety: SafetyConfig,
    pub log: LogConfig,
    pub rt: RtConfig,
    pub socket: SocketConfig,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinkKind {
    Serial,
    Can,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkConfig {
    pub kind: LinkKind,
    /// Serial device (or the pseudo-terminal of `arash mock-motor`).
    pub port: String,
    pub baud: u32,
    /// CAN interface.
    pub interface: String,
    /// Consecutive cycles without telemetry that latch a link timeout, in ms at the control
    /// rate (20 ms, as libfranka and the dVRK use).
    pub timeout_ms: f64,
    /// Torque ramp to zero after a link timeout (ms).
    pub ramp_ms: f64,
    /// The first valid telemetry must arrive within this time of start-up (ms).
    pub startup_timeout_ms: f64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            kind: LinkKind::Serial,
            port: "/dev/ttyUSB0".into(),
            baud: 2_000_000,
            interface: "can0".into(),
            timeout_ms: 20.0,
            ramp_ms: 10.0,
            startup_timeout_ms: 2000.0,
        }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlConfig {
    pub rate_hz: f64,
    /// pd, idc or robust.
    pub controller: String,
    /// A model file from `arash identify`; default: the CAD parameters of the URDF.
    pub model: Option<PathBuf>,
    /// How to read the paper's robust gains: si, deg-cm or deg-mm.
    pub gain_units: String,
    pub velocity_cutoff_hz: f64,
    /// Approach speed to a trajectory's start, as a fraction of the URDF speed limits.
    pub approach_fraction: f64,
}

impl Default for ControlConfig {
    fn default() -> Self {
        Self {
            rate_hz: 1000.0,
            controller: "robust".into(),
            model: None,
            gain_units: "si".into(),
            velocity_cutoff_hz: 50.0,
            approach_fraction: 0.25,
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetyConfig {
    /// Per-joint overrides of the limits derived from the URDF (see `SafetyLimits::from_model`).
    pub torque: Option<Vec<f64>>,
    pub torque_rate: Option<Vec<f64>>,
    pub velocity: Option<Vec<f64>>,
    pub margin: Option<Vec<f64>>,
    /// Following-error limit per joint; default 5° for rotations, 5 mm for insertion.
    pub following_error: Option<Vec<f64>>,
    /// Current mismatch: fraction of the torque limit, and how many cycles in a row.
    pub mismatch_fraction: Option<f64>,
    pub mismatch_cycles: Option<u32>,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RtConfig {
    pub policy: RtPolicy,
    pub priority: i32,
}

impl Default for RtConfig {
    fn default() -> Self {
        Self { policy: RtPolicy::Require, priority: 80 }
    }
}

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SocketConfig {
    /// The operator interface's Unix socket.
    pub path: PathBuf,
    /// Its file mode (octal text): who may command the robot.
    pub mode: String,
}

impl Default for SocketConfig {
    fn default() -> Self {
        Self { path: PathBuf::from("/run/arash/arash.sock"), mode: "0660".into() }
    }
}

impl SocketConfig {
    /// The socket's file mode, parsed from its octal text.
    pub fn mode_bits(&self) -> Result<u32, String> {
        u32::from_str_radix(self.mode.trim_start_matches("0o"), 8)
            .map_err(|_| format!("socket.mode must be octal, like \"0660\", not {:?}", self.mode))
    }
}

/// The daemon's name for a control law (configuration and `arash ctl controller`).
pub fn controller_kind(name: &str) -> Result<arash_core::control::ControllerKind, String> {
    use arash_core::control::ControllerKind;
    match name {
        "pd" => Ok(ControllerKind::Pd),
        "idc" => Ok(ControllerKind::Idc),
        "robust" => Ok(ControllerKind::Robust),
        other => Err(format!("must be pd, idc or robust, not {other:?}")),
    }
}

impl DaemonConfig {
    /// Read and check a configuration file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| anyhow::anyhow!("reading the configuration {}: {e}", path.display()))?;
        Self::parse(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
    }

    pub fn parse(text: &str) -> anyhow::Result<Self> {
        let config: DaemonConfig = toml::from_str(text)?;
        Ok(config)
    }

    /// Checks against the robot; the message names the offending key.
    pub fn validate(&self, model: &Model) -> Result<(), String> {
        let dof = model.dof();
        let positive = |key: &str, v: f64| -> Result<(), String> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{key} must be positive and finite, not {v}"))
            }
        };
        positive("link.timeout_ms", self.link.timeout_ms)?;
        positive("link.ramp_ms", self.link.ramp_ms)?;
        positive("link.startup_timeout_ms", self.link.startup_timeout_ms)?;
        positive("control.rate_hz", self.control.rate_hz)?;
        positive("control.velocity_cutoff_hz", self.control.velocity_cutoff_hz)?;
        positive("control.approach_fraction", self.control.approach_fraction)?;
        positive("log.rotate_mib", self.log.rotate_mib)?;
        positive("log.rotate_s", self.log.rotate_s)?;
        positive("log.blackbox_s", self.log.blackbox_s)?;
        if self.log.queue < 16 {
            return Err(format!("log.queue must be at least 16 cycles, not {}", self.log.queue));
        }
        if self.link.timeout_ms * self.control.rate_hz / 1000.0 < 1.0 {
            return Err(format!("link.timeout_ms = {} is shorter than one control period", self.link.timeout_ms));
        }
        if !(1..=99).contains(&self.rt.priority) {
            return Err(format!("rt.priority must be 1–99 (SCHED_FIFO), not {}", self.rt.priority));
        }
        self.socket.mode_bits()?;
        self.controller()?;
        self.control
            .gain_units
            .parse::<arash_core::control::gains::PaperUnits>()
            .map_err(|e| format!("control.gain_units: {e}"))?;
        self.drive.validate(dof)?;
        self.safety_limits(model)?.validate(dof).map_err(|e| format!("safety: {e}"))?;
        self.following_error(model)?;
        Ok(())
    }

    pub fn controller(&self) -> Result<arash_core::control::ControllerKind, String> {
        controller_kind(&self.control.controller).map_err(|e| format!("control.controller {e}"))
    }

    /// Cycles of the link timeout and of the ramp.
    pub fn link_cycles(&self) -> (u32, u32) {
        let cycles = |ms: f64| (ms * self.control.rate_hz / 1000.0).round().max(1.0) as u32;
        (cycles(self.link.timeout_ms), cycles(self.link.ramp_ms))
    }

    pub fn safety_limits(&self, model: &Model) -> Result<SafetyLimits, String> {
        let mut limits = SafetyLimits::from_model(model);
        let s = &self.safety;
        for (key, over, target) in [
            ("safety.torque", &s.torque, &mut limits.torque),
            ("safety.torque_rate", &s.torque_rate, &mut limits.torque_rate),
            ("safety.velocity", &s.velocity, &mut limits.velocity),
            ("safety.margin", &s.margin, &mut limits.margin),
        ] {
            if let Some(v) = over {
                if v.len() != model.dof() {
                    return Err(format!("{key} has {} entries; the robot has {} joints", v.len(), model.dof()));
                }
                target.clone_from(v);
            }
        }
        Ok(limits)
    }

    /// What the control cycle runs with.
    pub fn cycle_config(&self, model: &Model) -> Result<crate::rt::cycle::CycleConfig, String> {
        let (link_timeout, ramp) = self.link_cycles();
        Ok(crate::rt::cycle::CycleConfig {
            dt: 1.0 / self.control.rate_hz,
            drive: self.drive.clone(),
            limits: self.safety_limits(model)?,
            link_timeout,
            ramp,
            following_error: self.following_error(model)?,
            mismatch_fraction: self.safety.mismatch_fraction.unwrap_or(0.25),
            mismatch_cycles: self.safety.mismatch_cycles.unwrap_or(50),
            velocity_cutoff_hz: self.control.velocity_cutoff_hz,
            approach_speed: model.joints.iter().map(|j| self.control.approach_fraction * j.velocity).collect(),
        })
    }

    pub fn following_error(&self, model: &Model) -> Result<Vec<f64>, String> {
        let v = self.safety.following_error.clone().unwrap_or_else(|| {
            model
                .joints
                .iter()
                .map(|j| if matches!(j.kind, arash_core::JointKind::Prismatic) { 0.005 } else { 5f64.to_radians() })
                .collect()
        });
        if v.len() != model.dof() || v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(format!("safety.following_error must be {} positive numbers, not {v:?}", model.dof()));
        }
        Ok(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unknown_key_is_named() {
        let e = DaemonConfig::parse("[link]\ntimeout = 20\n").unwrap_err().to_string();
        assert!(e.contains("timeout"), "{e}");
    }

    #[test]
    fn a_bad_value_is_named() {
        let model = arash_core::arash_asist();
        let c = DaemonConfig::parse("[link]\ntimeout_ms = -1\n").unwrap();
        assert!(c.validate(&model).unwrap_err().contains("link.timeout_ms"));
        let c = DaemonConfig::parse("[drive]\ntorque_constant = [1.0, 2.0]\n").unwrap();
        assert!(c.validate(&model).unwrap_err().contains("drive.torque_constant"));
        let c = DaemonConfig::parse("[control]\ncontroller = \"lqr\"\n").unwrap();
        assert!(c.validate(&model).unwrap_err().contains("control.controller"));
        let c = DaemonConfig::parse("[socket]\nmode = \"rw\"\n").unwrap();
        assert!(c.validate(&model).unwrap_err().contains("socket.mode"));
    }

    #[test]
    fn the_shipped_configuration_is_valid_and_states_the_defaults() {
        let shipped = DaemonConfig::parse(include_str!("../../../deploy/daemon.toml")).unwrap();
        shipped.validate(&arash_core::arash_asist()).unwrap();
        let mut defaults = DaemonConfig::default();
        // The file rounds the torque constants to four digits.
        defaults.drive.torque_constant.clone_from(&shipped.drive.torque_constant);
        assert_eq!(shipped, defaults);
    }

    #[test]
    fn the_defaults_are_valid_and_give_a_20_cycle_timeout() {
        let model = arash_core::arash_asist();
        let c = DaemonConfig::default();
        c.validate(&model).unwrap();
        assert_eq!(c.link_cycles(), (20, 10));
    }
}
