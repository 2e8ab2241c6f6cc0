//! A CANopen master of CiA 402 drives in cyclic synchronous torque mode, as the daemon's
//! [`MotorLink`]: one drive per joint on one bus (docs/canopen.md).
//!
//! - [`CanopenLink::open`] puts every drive in pre-operational and disables its voltage, as soon
//!   as the bus is open; [`MotorLink::start`], on the control thread just before its first
//!   cycle, runs the rest of the start-up ([`drive_setup`](super::drive_setup)): checks, PDO
//!   mapping, mode, ratings, watchdogs, NMT start, with the master's heartbeat periodic
//!   throughout. A drive that does not answer or refuses any step is named and nothing is
//!   enabled.
//! - Each control cycle: one RPDO1 per drive and a SYNC in [`MotorLink::send`], the drives'
//!   TPDO1s, heartbeats and emergencies in [`MotorLink::poll`]. The daemon's motor currents map
//!   to ‰ of each drive's rated current (0x6075), which is ‰ of its rated torque (0x6076): the
//!   daemon's torque constants stay the one unit conversion.
//!
//! Any fault (a fault statusword, a drive that stops by itself, an EMCY, a lost heartbeat, a
//! node that reboots or leaves operational, the adapter's bus errors or lost frames, a torque
//! that is not a number) zeroes every torque, disables every axis and latches; telemetry reports
//! it as a fault bit every cycle, so that the cycle latches too. Only the operator's reset (the
//! first CLEAR_FAULT after another command) clears it: one fault-reset edge per drive in fault
//! (sent again only if the bus refused its frame), and the whole start-up again for a drive that
//! left operational. Missed TPDOs are missing telemetry: the cycle's link timeout latches them.

use std::time::{Duration, Instant};

use super::can::{BusHealth, CanBus, CanFrame};
use super::canopen::{heartbeat, nmt, sync, Emergency, ErrorClass, NmtCommand, NmtState, NodeId};
use super::cia402::{controlword, rpdo1, Axis, AxisFault, RatedScale, State, Tpdo1};
use super::drive_setup::{run, DriveInfo, DriveSetup, MasterHeartbeat, Scope, SetupError, SetupPoll, StartupError};
use super::frame::{drive_fault, status, Command, Telemetry, MAX_JOINTS};
use super::slcan::flags;
use super::{LinkStats, MotorLink};

pub use super::drive_setup::{AbortOption, CanopenConfig, CanopenConfigError, Transport};

/// Why the master latched its drives off; reported in telemetry as drive fault bits, and in
/// words in `arash ctl status`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MasterFault {
    /// A drive's statusword reported a fault.
    Drive {
        node: NodeId,
        statusword: u16,
    },
    /// A drive left operation enabled, or the walk to it, without the master commanding it.
    Stopped {
        node: NodeId,
        statusword: u16,
    },
    Emergency {
        node: NodeId,
        code: u16,
    },
    HeartbeatLost(NodeId),
    /// A drive left the operational state: a reboot (its boot-up message), or another master's
    /// NMT command.
    NotOperational {
        node: NodeId,
        state: NmtState,
    },
    /// The adapter or controller reported the bus in error, refused a frame, or lost frames.
    Bus(BusFault),
    /// The daemon asked for a torque that is not a number.
    NotFinite,
    /// The start-up of a drive the operator's reset brought back failed.
    Recovery(SetupError),
}

/// What the transport reported ([`BusHealth`]), with the adapter's status flags when it gave
/// them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusFault {
    Refused,
    BusError { flags: Option<u8> },
    Lost { flags: Option<u8> },
}

impl MasterFault {
    /// The telemetry fault bit: the EMCY's class where it has one of the drive's.
    pub fn bits(self) -> u8 {
        match self {
            Self::Emergency { code, .. } => match ErrorClass::of(code) {
                ErrorClass::Current => drive_fault::OVERCURRENT,
                ErrorClass::Voltage => drive_fault::UNDERVOLTAGE,
                ErrorClass::Temperature => drive_fault::OVERTEMPERATURE,
                ErrorClass::Sensor => drive_fault::ENCODER,
                ErrorClass::Communication | ErrorClass::Protocol => drive_fault::FIELDBUS,
                _ => drive_fault::DRIVE,
            },
            Self::Drive { .. } | Self::NotFinite => drive_fault::DRIVE,
            Self::Stopped { .. } => drive_fault::STOPPED,
            Self::HeartbeatLost(_) | Self::NotOperational { .. } | Self::Bus(_) | Self::Recovery(_) => {
                drive_fault::FIELDBUS
            }
        }
    }
}

impl std::fmt::Display for MasterFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::Drive { node, statusword } => {
                write!(
                    f,
                    "{node}: the drive reports a fault (state {}, statusword {statusword:#06x})",
                    State::of(statusword)
                )
            }
            Self::Stopped { node, statusword } => write!(
                f,
                "{node}: drive stopped by itself (state {}, statusword {statusword:#06x})",
                State::of(statusword)
            ),
            Self::Emergency { node, code } => {
                write!(f, "{node}: emergency {code:#06x} ({})", ErrorClass::of(code).name())
            }
            Self::HeartbeatLost(node) => write!(f, "{node}: heartbeat lost"),
            Self::NotOperational { node, state } => write!(f, "{node}: left operational ({state})"),
            Self::Bus(BusFault::Refused) => f.write_str("the CAN adapter refused a frame"),
            Self::Bus(BusFault::BusError { flags }) => write!(f, "the CAN bus is in error{}", Flags(flags)),
            Self::Bus(BusFault::Lost { flags }) => write!(f, "CAN frames were lost{}", Flags(flags)),
            Self::NotFinite => f.write_str("a torque that is not a number was asked for"),
            Self::Recovery(e) => write!(f, "the start-up after the reset failed: {e}"),
        }
    }
}

/// The adapter's status flags in words, or what reported the error without them.
struct Flags(Option<u8>);

impl std::fmt::Display for Flags {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(bits) => {
                write!(f, " (adapter status {bits:#04x}:")?;
                for name in flags::names(bits) {
                    write!(f, " {name};")?;
                }
                f.write_str(" docs/canopen.md, \"Faults\")")
            }
            None => f.write_str(" (reported by the CAN controller or the host's receive queue)"),
        }
    }
}

/// SYNCs whose times are kept: far more than the sets in flight on a bus at 1 kHz.
const SYNC_RING: usize = 64;

/// The drives, run once per control cycle.
pub struct CanopenLink<B> {
    bus: B,
    config: CanopenConfig,
    sync_period: Duration,
    /// The start-up has run: until then the link sends and reads nothing.
    started: bool,
    nodes: [Option<NodeId>; MAX_JOINTS],
    joints: usize,
    axes: [Axis; MAX_JOINTS],
    /// Each drive's currents in ‰ of its rated current (0x6075), limited to 0x6072.
    scales: [Option<RatedScale>; MAX_JOINTS],
    last_heartbeat: [Instant; MAX_JOINTS],
    /// Each drive known to be operational and configured: a boot-up, a heartbeat in another
    /// state, or a lost heartbeat clears it, and the operator's reset then runs its start-up
    /// again ([`Scope::Recover`]) in `recovery`, a transfer per cycle.
    operational: [bool; MAX_JOINTS],
    recovery: [Option<DriveSetup>; MAX_JOINTS],
    heartbeat_timeout: Duration,
    beat: MasterHeartbeat,
    /// The TPDO1 set of this SYNC, and which joints it has.
    partial: Telemetry,
    have: u32,
    sets: u16,
    zero: [i32; MAX_JOINTS],
    opened: Instant,
    /// When each of the last SYNCs was sent (µs since the link opened), by SYNC number: a set
    /// of TPDOs is stamped with the time of the SYNC it answers, at which the drives sampled it,
    /// not with the time it arrived.
    sync_times: [u32; SYNC_RING],
    syncs_sent: u32,
    /// The number of the SYNC the next complete set answers.
    answered: u32,
    /// The transport's report when the latch was last cleared: what it adds since latches.
    bus_seen: BusHealth,
    latched: Option<MasterFault>,
    /// The last command was CLEAR_FAULT: the operator's reset is under way.
    clearing: bool,
    /// SYNCs are stamped with their number times the SYNC period, not the host's clock
    /// ([`MotorLink::clock_by_samples`]).
    by_samples: bool,
    stats: LinkStats,
}

impl<B: CanBus> CanopenLink<B> {
    /// The drives of `config` on `bus`, as soon as it is open: every drive put in
    /// pre-operational and its voltage disabled (a drive left enabled by a daemon that crashed
    /// is switched off before anything else). The rest of the start-up is [`MotorLink::start`].
    pub fn open(mut bus: B, config: &CanopenConfig, sync_period: Duration) -> Result<Self, StartupError> {
        bus.send(&nmt(NmtCommand::EnterPreOperational, None)).map_err(StartupError::Bus)?;
        let mut setups: Vec<DriveSetup> =
            config.nodes.iter().map(|&n| DriveSetup::new(n, config, sync_period, Scope::Disable)).collect();
        run(&mut bus, &mut setups, None)?;
        Ok(Self::with(bus, config, sync_period))
    }

    /// The link over drives that the start-up has already configured and started (tests, and
    /// the fuzz target).
    pub fn new(bus: B, config: &CanopenConfig, drives: &[DriveInfo]) -> Self {
        let mut link = Self::with(bus, config, Duration::from_millis(1));
        link.started_with(drives);
        link
    }

    fn with(bus: B, config: &CanopenConfig, sync_period: Duration) -> Self {
        assert!(config.nodes.len() <= MAX_JOINTS);
        let now = Instant::now();
        let mut nodes = [None; MAX_JOINTS];
        for (slot, &node) in nodes.iter_mut().zip(&config.nodes) {
            *slot = Some(node);
        }
        let bus_seen = bus.health();
        Self {
            bus,
            config: config.clone(),
            sync_period,
            started: false,
            nodes,
            joints: config.nodes.len(),
            axes: [Axis::default(); MAX_JOINTS],
            scales: [None; MAX_JOINTS],
            last_heartbeat: [now; MAX_JOINTS],
            operational: [false; MAX_JOINTS],
            recovery: [const { None }; MAX_JOINTS],
            heartbeat_timeout: Duration::from_millis(u64::from(config.heartbeat_timeout_ms)),
            beat: MasterHeartbeat::new(config),
            partial: Telemetry::new(config.nodes.len()),
            have: 0,
            sets: 0,
            zero: [0; MAX_JOINTS],
            opened: now,
            sync_times: [0; SYNC_RING],
            syncs_sent: 0,
            answered: 0,
            bus_seen,
            latched: None,
            clearing: false,
            by_samples: false,
            stats: LinkStats { bus: Some(bus_seen), ..LinkStats::default() },
        }
    }

    fn started_with(&mut self, drives: &[DriveInfo]) {
        assert!(drives.len() == self.joints);
        let now = Instant::now();
        for (j, d) in drives.iter().enumerate() {
            self.scales[j] = RatedScale::new(d.rated_current_ma, self.config.max_torque_permille);
            assert!(self.scales[j].is_some(), "the start-up refuses a drive rated for no current");
            self.operational[j] = true;
            self.last_heartbeat[j] = now;
        }
        self.started = true;
    }

    /// The fault the master latched, if any.
    pub fn latched(&self) -> Option<MasterFault> {
        self.latched
    }

    /// Latch every axis off for `fault`; the first fault is the one kept.
    fn latch(&mut self, fault: MasterFault) {
        self.latched.get_or_insert(fault);
        self.stats.latched = self.latched;
        for axis in &mut self.axes[..self.joints] {
            axis.latch(AxisFault::Master);
        }
    }

    fn joint_of(&self, node: NodeId) -> Option<usize> {
        self.nodes[..self.joints].iter().position(|n| *n == Some(node))
    }

    fn node(&self, j: usize) -> NodeId {
        self.nodes[j].expect("a node per joint")
    }

    /// The operator's reset: clear the latch, send each drive in fault one reset edge, give the
    /// heartbeats a fresh timeout, and start again every drive not known to be operational.
    fn reset(&mut self) {
        self.latched = None;
        self.stats.latched = None;
        self.bus_seen = self.bus.health();
        let now = Instant::now();
        for j in 0..self.joints {
            self.axes[j].reset();
            self.last_heartbeat[j] = now;
            if !self.operational[j] && self.recovery[j].is_none() {
                self.recovery[j] = Some(DriveSetup::new(self.node(j), &self.config, self.sync_period, Scope::Recover));
            }
        }
    }

    /// One step of each recovery under way: a frame to send, or its end.
    fn recover(&mut self, now: Instant) -> std::io::Result<()> {
        let mut result = Ok(());
        for j in 0..self.joints {
            let Some(setup) = self.recovery[j].as_mut() else { continue };
            match setup.poll(now, true) {
                SetupPoll::Busy => {}
                SetupPoll::Send(frame) => result = result.and(self.send_frame(&frame)),
                SetupPoll::Done(info) => {
                    self.recovery[j] = None;
                    self.operational[j] = true;
                    self.last_heartbeat[j] = now;
                    self.scales[j] = RatedScale::new(info.rated_current_ma, self.config.max_torque_permille);
                }
                SetupPoll::Failed(e) => {
                    self.recovery[j] = None;
                    self.latch(MasterFault::Recovery(e));
                }
            }
        }
        self.stats.recovering = (0..self.joints).fold(0, |m, j| m | u8::from(self.recovery[j].is_some()) << j);
        result
    }

    /// The target torque of joint `j` for `amps`, zero unless its axis may have one.
    fn permille(&mut self, j: usize, amps: f32) -> i16 {
        let Some(scale) = self.scales[j] else { return 0 };
        match scale.permille(f64::from(amps)) {
            Err(_) => {
                self.latch(MasterFault::NotFinite);
                0
            }
            Ok(_) if !self.axes[j].torque_allowed() => 0,
            Ok(permille) => permille,
        }
    }

    fn send_frame(&mut self, frame: &CanFrame) -> std::io::Result<()> {
        self.bus.send(frame).inspect_err(|_| self.stats.send_errors += 1)
    }

    /// Fold one TPDO1 into this SYNC's set; `true` completes it.
    fn absorb(&mut self, j: usize, pdo: &Tpdo1) -> bool {
        self.axes[j].observe(pdo.statusword);
        match self.axes[j].latched() {
            Some(AxisFault::Drive { statusword }) => self.latch(MasterFault::Drive { node: pdo.node, statusword }),
            Some(AxisFault::Stopped { statusword }) => self.latch(MasterFault::Stopped { node: pdo.node, statusword }),
            Some(AxisFault::Master) | None => {}
        }
        if self.have & (1 << j) != 0 {
            // The last set never completed: a TPDO was missed (none is while a drive is being
            // brought back: it sends none until its NMT start).
            self.stats.lost += u64::from(self.stats.recovering == 0);
            self.have = 0;
            self.answered = self.answered.wrapping_add(1);
        }
        self.partial.counts[j] = pdo.position.wrapping_sub(self.zero[j]);
        self.partial.amps[j] = self.scales[j].map_or(0.0, |s| s.value(pdo.torque_permille)) as f32;
        self.have |= 1 << j;
        self.have == (1 << self.joints) - 1
    }

    fn on_frame(&mut self, frame: &CanFrame, out: &mut Telemetry, now: Instant) -> bool {
        for setup in self.recovery[..self.joints].iter_mut().flatten() {
            setup.on_frame(frame, now);
        }
        if let Some(pdo) = Tpdo1::parse(frame) {
            if let Some(j) = self.joint_of(pdo.node) {
                if self.absorb(j, &pdo) {
                    self.have = 0;
                    self.sets = self.sets.wrapping_add(1);
                    self.finish(out);
                    return true;
                }
            }
            return false;
        }
        if let Some(emcy) = Emergency::parse(frame) {
            if self.joint_of(emcy.node).is_some() && emcy.is_error() {
                self.latch(MasterFault::Emergency { node: emcy.node, code: emcy.code });
            }
            return false;
        }
        if let Some((node, state)) = heartbeat(frame) {
            if let Some(j) = self.joint_of(node) {
                self.last_heartbeat[j] = now;
                // A drive being brought back reports pre-operational until its NMT start.
                if state != NmtState::Operational && self.recovery[j].is_none() {
                    self.operational[j] = false;
                    self.latch(MasterFault::NotOperational { node, state });
                }
            }
        }
        // Other traffic on a shared bus (SDO answers, other nodes) is harmless.
        false
    }

    /// The time of the SYNC the set just completed answers. Sets answer SYNCs in order; one
    /// that would answer a SYNC not yet sent, or one older than the ring holds, answers the
    /// last one sent.
    fn answered_sync_time(&mut self) -> u32 {
        let behind = self.syncs_sent.wrapping_sub(self.answered);
        if behind == 0 || behind as usize > SYNC_RING {
            self.answered = self.syncs_sent.wrapping_sub(1);
        }
        let time = self.sync_times[self.answered as usize % SYNC_RING];
        self.answered = self.answered.wrapping_add(1);
        time
    }

    /// The telemetry of a complete set.
    fn finish(&mut self, out: &mut Telemetry) {
        let enabled = self.axes[..self.joints].iter().all(|a| a.state() == State::OperationEnabled);
        self.partial.seq = self.sets;
        self.partial.ack_seq = self.sets;
        self.partial.device_time_us = self.answered_sync_time();
        self.partial.status = if enabled { status::ENABLED } else { 0 };
        *out = self.partial;
        self.stats.frames_received += 1;
    }

    /// What telemetry reports: the latched fault, and any drive that is in fault (one that has
    /// been sent a reset and not yet left its fault is not latched again, but is reported).
    fn fault_bits(&self) -> u8 {
        let in_fault = self.axes[..self.joints].iter().any(|a| a.state().is_fault());
        self.latched.map_or(0, MasterFault::bits) | if in_fault { drive_fault::DRIVE } else { 0 }
    }

    fn check_watchdogs(&mut self, now: Instant) {
        for j in 0..self.joints {
            let silent = now.duration_since(self.last_heartbeat[j]) > self.heartbeat_timeout;
            if silent && self.recovery[j].is_none() {
                // Whatever it did while silent (a power cycle, a cable), it is not known to be
                // configured any more.
                self.operational[j] = false;
                self.latch(MasterFault::HeartbeatLost(self.node(j)));
            }
        }
        let health = self.bus.health();
        self.stats.bus = Some(health);
        let (seen, flags) = (self.bus_seen, health.status_flags);
        let fault = if health.bus_errors > seen.bus_errors {
            Some(BusFault::BusError { flags })
        } else if health.overruns > seen.overruns {
            Some(BusFault::Lost { flags })
        } else if health.refused > seen.refused {
            Some(BusFault::Refused)
        } else {
            None
        };
        if let Some(fault) = fault {
            self.bus_seen = health;
            self.latch(MasterFault::Bus(fault));
        }
    }
}

impl<B: CanBus> MotorLink for CanopenLink<B> {
    /// The start-up after [`CanopenLink::open`]: every drive configured (together, each on its
    /// own SDO channel), then started, with the master's heartbeat periodic from the first
    /// transfer on and from then on every cycle.
    fn start(&mut self) -> Result<Vec<String>, Box<dyn std::error::Error + Send + Sync>> {
        if self.started {
            return Ok(Vec::new());
        }
        let mut setups: Vec<DriveSetup> = self.config.nodes[..self.joints]
            .iter()
            .map(|&n| DriveSetup::new(n, &self.config, self.sync_period, Scope::Configure))
            .collect();
        let drives = run(&mut self.bus, &mut setups, Some(&mut self.beat))?;
        self.started_with(&drives);
        self.bus_seen = self.bus.health();
        Ok(drives.iter().map(|d| format!("CiA 402 drive {d}; cyclic synchronous torque, disabled")).collect())
    }

    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        if !self.started {
            return Ok(());
        }
        let clearing = matches!(command, Command::ClearFault);
        if clearing && !self.clearing {
            self.reset();
        }
        self.clearing = clearing;
        match command {
            Command::Enable => {
                for j in 0..self.joints {
                    // A latched axis stays off (the telemetry's fault bit tells the cycle), and
                    // so does one being brought back.
                    if self.recovery[j].is_none() {
                        let _ = self.axes[j].enable();
                    }
                }
            }
            Command::Disable => self.axes[..self.joints].iter_mut().for_each(Axis::disable),
            Command::ZeroEncoders => {
                for j in 0..self.joints {
                    self.zero[j] = self.zero[j].wrapping_add(self.partial.counts[j]);
                }
            }
            Command::Current { .. } | Command::Heartbeat | Command::ClearFault => {}
        }
        let amps = match command {
            Command::Current { amps, .. } => *amps,
            _ => [0.0; MAX_JOINTS],
        };
        let mut result = Ok(());
        for (j, &a) in amps.iter().enumerate().take(self.joints) {
            let torque = self.permille(j, a);
            let word = self.axes[j].controlword();
            let sent = self.send_frame(&rpdo1(self.node(j), word, torque));
            if sent.is_err() && word & controlword::FAULT_RESET != 0 {
                // A refused frame never reached the bus: the edge goes again.
                self.axes[j].edge_lost();
            }
            result = result.and(sent);
        }
        let now = Instant::now();
        let stamp = match self.by_samples {
            true => u64::from(self.syncs_sent) * self.sync_period.as_micros() as u64,
            false => now.duration_since(self.opened).as_micros() as u64,
        };
        self.sync_times[self.syncs_sent as usize % SYNC_RING] = stamp as u32;
        self.syncs_sent = self.syncs_sent.wrapping_add(1);
        result = result.and(self.send_frame(&sync()));
        if let Some(beat) = self.beat.due(now) {
            result = result.and(self.send_frame(&beat));
        }
        result = result.and(self.recover(now));
        result = result.and(self.bus.service());
        self.stats.frames_sent += 1;
        result
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        if !self.started {
            return Ok(false);
        }
        let now = Instant::now();
        let mut fresh = false;
        while let Some(frame) = self.bus.receive()? {
            fresh |= self.on_frame(&frame, out, now);
        }
        self.check_watchdogs(now);
        // After every frame and watchdog of this poll, and with or without a new set: the
        // cycle hears of a fault even while a drive sends nothing.
        out.faults = self.fault_bits();
        Ok(fresh)
    }

    fn stats(&self) -> LinkStats {
        self.stats
    }

    fn wait(&mut self, timeout: Duration) {
        self.bus.wait(timeout);
    }

    fn clock_by_samples(&mut self) {
        self.by_samples = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::can::InProcessBus;

    fn started(joints: u8) -> (CanopenLink<InProcessBus>, InProcessBus) {
        let config = CanopenConfig {
            nodes: (1..=joints).map(|n| NodeId::try_from(n).unwrap()).collect(),
            ..CanopenConfig::default()
        };
        let drives: Vec<DriveInfo> = config
            .nodes
            .iter()
            .map(|&node| DriveInfo {
                node,
                vendor: 0,
                product: 0,
                rated_current_ma: 1000,
                rated_torque_mnm: 100,
                statusword: 0x0250,
            })
            .collect();
        let (host, drives_bus) = InProcessBus::pair(1024);
        (CanopenLink::new(host, &config, &drives), drives_bus)
    }

    fn tpdo(node: u8, statusword: u16) -> CanFrame {
        Tpdo1 { node: NodeId::try_from(node).unwrap(), statusword, position: 0, torque_permille: 0 }.frame()
    }

    /// The controlwords of the RPDO1s the master sent since the last call, per node.
    fn controlwords(bus: &mut InProcessBus, node: u8) -> Vec<u16> {
        let mut words = Vec::new();
        while let Ok(Some(f)) = bus.receive() {
            if f.id == 0x200 + u32::from(node) {
                words.push(u16::from_le_bytes([f.data[0], f.data[1]]));
            }
        }
        words
    }

    /// A cycle of the master against one drive that answers `statusword`.
    fn cycle(link: &mut CanopenLink<InProcessBus>, drive: &mut InProcessBus, command: Command, statusword: u16) -> u8 {
        link.send(&command).unwrap();
        drive.send(&tpdo(1, statusword)).unwrap();
        let mut t = Telemetry::new(1);
        link.poll(&mut t).unwrap();
        t.faults
    }

    /// The e-stop case of issue 57: the drive goes through quick stop active to switch on
    /// disabled with no fault bit. The master latches in the cycle it sees quick stop active,
    /// names the state, reports it every cycle, and sends disable voltage from then on.
    #[test]
    fn a_drive_that_stops_by_itself_is_latched_named_and_only_disabled() {
        let (mut link, mut drive) = started(1);
        let current = Command::Current { joints: 1, amps: [0.1; MAX_JOINTS] };
        cycle(&mut link, &mut drive, Command::Enable, 0x0250);
        for statusword in [0x0231, 0x0233, 0x1237, 0x1237] {
            assert_eq!(cycle(&mut link, &mut drive, current, statusword), 0);
        }
        controlwords(&mut drive, 1);
        assert_eq!(cycle(&mut link, &mut drive, current, 0x0217), drive_fault::STOPPED);
        for _ in 0..5 {
            assert_eq!(cycle(&mut link, &mut drive, current, 0x0250), drive_fault::STOPPED, "reported every cycle");
        }
        assert_eq!(controlwords(&mut drive, 1), [0x0F, 0, 0, 0, 0, 0], "never walked back");
        let latched = link.latched().unwrap();
        assert_eq!(latched, MasterFault::Stopped { node: NodeId::try_from(1).unwrap(), statusword: 0x0217 });
        assert_eq!(latched.to_string(), "node 1: drive stopped by itself (state quick stop active, statusword 0x0217)");
        assert_eq!(link.stats().latched, Some(latched));
        // The operator's reset, then enable: walked again from switch on disabled.
        assert_eq!(cycle(&mut link, &mut drive, Command::ClearFault, 0x0250), 0);
        cycle(&mut link, &mut drive, Command::Enable, 0x0250);
        cycle(&mut link, &mut drive, current, 0x0250);
        assert_eq!(controlwords(&mut drive, 1), [0, 0x06, 0x06]);
    }

    /// Error passive, bus error and lost frames reported by the transport latch `fieldbus`
    /// with the adapter's flags named; an error warning alone does not.
    #[test]
    fn the_transports_reports_latch_by_kind() {
        let fault = BusFault::BusError { flags: Some(0x20) };
        assert_eq!(MasterFault::Bus(fault).bits(), drive_fault::FIELDBUS);
        assert_eq!(
            MasterFault::Bus(fault).to_string(),
            "the CAN bus is in error (adapter status 0x20: error passive; docs/canopen.md, \"Faults\")"
        );
        let lost = MasterFault::Bus(BusFault::Lost { flags: Some(0x08) });
        assert!(lost.to_string().contains("data overrun"), "{lost}");
    }
}
