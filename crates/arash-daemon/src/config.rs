//! The daemon's configuration file (TOML). Every table and key is optional; unknown keys are
//! errors that name the key, and values are checked with messages that name it too. Units are
//! SI (rad, m, N·m, N, s) unless the key says otherwise (`_ms`, `_hz`, `_mib`).

use std::path::{Path, PathBuf};

use arash_core::control::SafetyLimits;
use arash_core::Model;

use crate::drive_config::DriveConfig;
use crate::link::master::CanopenConfig;
use crate::live::LiveConfig;
use crate::logger::LogConfig;
use crate::rt::clock::{Pace, RtPolicy};

#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DaemonConfig {
    /// The robot's URDF; default: the bundled ARASH:ASiST.
    pub robot: Option<PathBuf>,
    pub link: LinkConfig,
    /// The drives of `link.kind = "canopen"`.
    pub canopen: CanopenConfig,
    pub drive: DriveConfig,
    pub control: ControlConfig,
    pub safety: SafetyConfig,
    pub log: LogConfig,
    pub rt: RtConfig,
    pub socket: SocketConfig,
    pub live: LiveConfig,
    pub force: crate::rt::force::ForceConfig,
    pub haptic: crate::rt::haptic::HapticConfig,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum LinkKind {
    /// arash's own protocol on a serial line (docs/protocol.md).
    Serial,
    /// arash's own protocol on SocketCAN.
    Can,
    /// CiA 402 drives over CANopen (docs/canopen.md), configured by `[canopen]`.
    Canopen,
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
    /// Cycles without telemetry repeat the last command for this long (ms); after it, until
    /// telemetry returns or the link times out, they command the control law at the reference
    /// (its feed-forward). See `rt::cycle`, "stale telemetry".
    pub hold_ms: f64,
    /// The first valid telemetry must arrive within this time of start-up (ms).
    pub startup_timeout_ms: f64,
    /// A drive the host enables must report its power stage on within this time (ms), or
    /// `DRIVE_STOPPED` latches. Not the link timeout: a CiA 402 drive walks three states to
    /// get there, one process-data round trip each, and a drive that releases a brake or
    /// charges its DC link first takes tens to hundreds of milliseconds; until it confirms, it
    /// applies no torque, so the wait costs nothing in safety.
    pub enable_timeout_ms: f64,
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
            hold_ms: 3.0,
            startup_timeout_ms: 2000.0,
            enable_timeout_ms: 1000.0,
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
    /// `deadline` (the rig), or `lockstep` for a simulated rig: each cycle as soon as the link
    /// answers the last (rt/clock.rs, [`Pace`]). Lockstep needs `policy = "ignore"`.
    pub pace: Pace,
}

impl Default for RtConfig {
    fn default() -> Self {
        Self { policy: RtPolicy::Require, priority: 80, pace: Pace::Deadline }
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
    pub fn mode_bits(&self) -> Result<u32, ConfigError> {
        u32::from_str_radix(self.mode.trim_start_matches("0o"), 8)
            .map_err(|_| ConfigError::SocketMode(self.mode.clone()))
    }
}

/// The daemon's name for a control law (configuration and `arash ctl controller`).
pub fn controller_kind(name: &str) -> Result<arash_core::control::ControllerKind, UnknownController> {
    use arash_core::control::ControllerKind;
    match name {
        "pd" => Ok(ControllerKind::Pd),
        "idc" => Ok(ControllerKind::Idc),
        "robust" => Ok(ControllerKind::Robust),
        other => Err(UnknownController(other.to_string())),
    }
}

impl DaemonConfig {
    /// Read and check a configuration file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let read = |e: std::io::Error| ConfigError::Read(path.display().to_string(), e);
        let text = std::fs::read_to_string(path).map_err(read)?;
        Self::parse(&text).map_err(|e| match e {
            ConfigError::Toml(_, source) => ConfigError::Toml(path.display().to_string(), source),
            other => other,
        })
    }

    pub fn parse(text: &str) -> Result<Self, ConfigError> {
        toml::from_str(text).map_err(|e| ConfigError::Toml("the configuration".into(), e))
    }

    /// Checks against the robot; the error names the offending key.
    pub fn validate(&self, model: &Model) -> Result<(), ConfigError> {
        let dof = model.dof();
        let positive = |key: &'static str, value: f64| -> Result<(), ConfigError> {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(ConfigError::NotPositive { key, value })
            }
        };
        positive("link.timeout_ms", self.link.timeout_ms)?;
        positive("link.ramp_ms", self.link.ramp_ms)?;
        if !(self.link.hold_ms.is_finite() && (0.0..self.link.timeout_ms).contains(&self.link.hold_ms)) {
            return Err(ConfigError::Hold { hold: self.link.hold_ms, timeout: self.link.timeout_ms });
        }
        positive("link.startup_timeout_ms", self.link.startup_timeout_ms)?;
        positive("link.enable_timeout_ms", self.link.enable_timeout_ms)?;
        positive("control.rate_hz", self.control.rate_hz)?;
        positive("control.velocity_cutoff_hz", self.control.velocity_cutoff_hz)?;
        positive("control.approach_fraction", self.control.approach_fraction)?;
        positive("log.rotate_mib", self.log.rotate_mib)?;
        positive("log.rotate_s", self.log.rotate_s)?;
        positive("log.blackbox_s", self.log.blackbox_s)?;
        if self.log.queue < 16 {
            return Err(ConfigError::Queue(self.log.queue));
        }
        if self.link.timeout_ms * self.control.rate_hz / 1000.0 < 1.0 {
            return Err(ConfigError::TimeoutBelowPeriod(self.link.timeout_ms));
        }
        if self.rt.pace == Pace::Lockstep && self.rt.policy == RtPolicy::Require {
            return Err(ConfigError::LockstepOnRig);
        }
        if !(1..=99).contains(&self.rt.priority) {
            return Err(ConfigError::Priority(self.rt.priority.into()));
        }
        self.socket.mode_bits()?;
        self.live.validate()?;
        self.controller()?;
        self.control.gain_units.parse::<arash_core::control::gains::PaperUnits>().map_err(ConfigError::GainUnits)?;
        self.drive.validate(dof)?;
        if self.link.kind == LinkKind::Canopen {
            self.canopen.validate(dof)?;
        }
        self.safety_limits(model)?.validate(dof)?;
        self.following_error(model)?;
        self.force.validate(model).map_err(ConfigError::Force)?;
        self.haptic.validate().map_err(ConfigError::Haptic)?;
        if self.haptic.acceleration_cutoff_hz >= 0.5 * self.control.rate_hz {
            return Err(ConfigError::Haptic(format!(
                "haptic.acceleration_cutoff_hz = {} is not below the loop's Nyquist frequency, {} Hz",
                self.haptic.acceleration_cutoff_hz,
                0.5 * self.control.rate_hz
            )));
        }
        Ok(())
    }

    pub fn controller(&self) -> Result<arash_core::control::ControllerKind, ConfigError> {
        Ok(controller_kind(&self.control.controller)?)
    }

    /// Cycles of the link timeout, of the ramp and of the hold.
    pub fn link_cycles(&self) -> (u32, u32, u32) {
        // A hold may be nil; a timeout or a ramp lasts at least a cycle.
        (
            self.cycles(self.link.timeout_ms).max(1),
            self.cycles(self.link.ramp_ms).max(1),
            self.cycles(self.link.hold_ms),
        )
    }

    /// A time in ms as whole control cycles.
    fn cycles(&self, ms: f64) -> u32 {
        (ms * self.control.rate_hz / 1000.0).round() as u32
    }

    pub fn safety_limits(&self, model: &Model) -> Result<SafetyLimits, ConfigError> {
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
                    return Err(ConfigError::Length { key, got: v.len(), dof: model.dof() });
                }
                target.clone_from(v);
            }
        }
        Ok(limits)
    }

    /// What the control cycle runs with.
    pub fn cycle_config(&self, model: &Model) -> Result<crate::rt::cycle::CycleConfig, ConfigError> {
        let (link_timeout, ramp, hold) = self.link_cycles();
        Ok(crate::rt::cycle::CycleConfig {
            dt: 1.0 / self.control.rate_hz,
            drive: self.drive.clone(),
            limits: self.safety_limits(model)?,
            link_timeout,
            enable_timeout: self.cycles(self.link.enable_timeout_ms).max(1),
            ramp,
            hold,
            following_error: self.following_error(model)?,
            mismatch_fraction: self.safety.mismatch_fraction.unwrap_or(0.25),
            mismatch_cycles: self.safety.mismatch_cycles.unwrap_or(50),
            velocity_cutoff_hz: self.control.velocity_cutoff_hz,
            approach_speed: model.joints.iter().map(|j| self.control.approach_fraction * j.velocity).collect(),
            handover: self.cycles(self.haptic.handover_ms).max(1),
        })
    }

    pub fn following_error(&self, model: &Model) -> Result<Vec<f64>, ConfigError> {
        let v = self.safety.following_error.clone().unwrap_or_else(|| {
            model
                .joints
                .iter()
                .map(|j| if matches!(j.kind, arash_core::JointKind::Prismatic) { 0.005 } else { 5f64.to_radians() })
                .collect()
        });
        if v.len() != model.dof() || v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(ConfigError::FollowingError { dof: model.dof(), got: v });
        }
        Ok(v)
    }
}

/// A control law's name that is not one of the daemon's.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("must be pd, idc or robust, not {0:?}")]
pub struct UnknownController(pub String);

/// Why a configuration cannot run the rig; each names the key.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("reading the configuration {0}: {1}")]
    Read(String, #[source] std::io::Error),
    #[error("{0}: {1}")]
    Toml(String, #[source] toml::de::Error),
    #[error("{key} must be positive and finite, not {value}")]
    NotPositive { key: &'static str, value: f64 },
    #[error("link.hold_ms must be at least 0 and shorter than link.timeout_ms = {timeout}, not {hold}")]
    Hold { hold: f64, timeout: f64 },
    #[error("log.queue must be at least 16 cycles, not {0}")]
    Queue(usize),
    #[error("link.timeout_ms = {0} is shorter than one control period")]
    TimeoutBelowPeriod(f64),
    #[error(
        "rt.pace = \"lockstep\" runs the loop as fast as the link answers, which only a simulated rig may do; \
         it needs rt.policy = \"ignore\" (--rt ignore)"
    )]
    LockstepOnRig,
    #[error("rt.priority must be 1–99 (SCHED_FIFO), not {0}")]
    Priority(i64),
    #[error("socket.mode must be octal, like \"0660\", not {0:?}")]
    SocketMode(String),
    #[error(transparent)]
    Live(#[from] crate::live::LiveConfigError),
    #[error("control.controller {0}")]
    Controller(#[from] UnknownController),
    #[error("control.gain_units: {0}")]
    GainUnits(String),
    #[error(transparent)]
    Drive(#[from] crate::drive_config::DriveConfigError),
    #[error(transparent)]
    Canopen(#[from] crate::link::master::CanopenConfigError),
    #[error("safety: {0}")]
    Safety(#[from] arash_core::control::LimitsError),
    #[error("{key} has {got} entries; the robot has {dof} joints")]
    Length { key: &'static str, got: usize, dof: usize },
    #[error("{0}")]
    Force(String),
    #[error("{0}")]
    Haptic(String),
    #[error("safety.following_error must be {dof} positive numbers, not {got:?}")]
    FollowingError { dof: usize, got: Vec<f64> },
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
        assert!(c.validate(&model).unwrap_err().to_string().contains("link.timeout_ms"));
        for hold in ["-1", "20"] {
            let c = DaemonConfig::parse(&format!("[link]\nhold_ms = {hold}\n")).unwrap();
            assert!(c.validate(&model).unwrap_err().to_string().contains("link.hold_ms"), "{hold}");
        }
        let c = DaemonConfig::parse("[drive]\ntorque_constant = [1.0, 2.0]\n").unwrap();
        assert!(c.validate(&model).unwrap_err().to_string().contains("drive.torque_constant"));
        let c = DaemonConfig::parse("[control]\ncontroller = \"lqr\"\n").unwrap();
        assert!(c.validate(&model).unwrap_err().to_string().contains("control.controller"));
        let c = DaemonConfig::parse("[socket]\nmode = \"rw\"\n").unwrap();
        assert!(c.validate(&model).unwrap_err().to_string().contains("socket.mode"));
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
    fn the_force_observers_settings_are_checked_by_name() {
        let model = arash_core::arash_asist();
        let refused = |text: &str, key: &str| {
            let e = DaemonConfig::parse(text).unwrap().validate(&model).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        };
        refused("[force]\nbandwidth_hz = [20.0, 20.0]\n", "force.bandwidth_hz has 2 entries");
        refused("[force]\ncontact = [0.1, 0.1, 1.0]\n", "force.contact and force.collision go together");
        refused("[force]\ncontact = [0.1, 0.1, 1.0]\ncollision = [0.2, 0.05, 2.0]\n", "below force.contact");
        refused("[force]\ncollision_sigmas = 2.0\n", "force.collision_sigmas is below");
        assert!(DaemonConfig::parse("[force]\nfram = \"tip\"\n").unwrap_err().to_string().contains("fram"));
        refused("[force]\nframe = \"tool\"\n", "force.frame");
        DaemonConfig::parse("[force]\nframe = \"remote_centre\"\n").unwrap().validate(&model).unwrap();
    }

    #[test]
    fn the_haptic_modes_settings_are_checked_by_name() {
        let model = arash_core::arash_asist();
        for (text, key) in [
            ("[haptic]\nviscous_compensation = 1.0\n", "haptic.viscous_compensation"),
            ("[haptic]\nlatency_ms = -1.0\n", "haptic.latency_ms"),
            ("[haptic]\nhandover_ms = nan\n", "haptic.handover_ms"),
            ("[haptic]\ninertia_compensation = 1.0\n", "haptic.inertia_compensation"),
            ("[haptic]\ninertia_compensation = -0.1\n", "haptic.inertia_compensation"),
            ("[haptic]\nacceleration_cutoff_hz = 0.0\n", "haptic.acceleration_cutoff_hz"),
            ("[haptic]\nacceleration_cutoff_hz = 500.0\n", "haptic.acceleration_cutoff_hz = 500 is not below"),
        ] {
            let e = DaemonConfig::parse(text).unwrap().validate(&model).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
        DaemonConfig::parse("[haptic]\ninertia_compensation = 0.5\n").unwrap().validate(&model).unwrap();
    }

    #[test]
    fn the_defaults_are_valid_and_give_a_20_cycle_timeout() {
        let model = arash_core::arash_asist();
        let c = DaemonConfig::default();
        c.validate(&model).unwrap();
        assert_eq!(c.link_cycles(), (20, 10, 3));
        assert_eq!(c.cycle_config(&model).unwrap().enable_timeout, 1000);
    }
}
