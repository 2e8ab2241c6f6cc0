//! A CANopen master of CiA 402 drives in cyclic synchronous torque mode, as the daemon's
//! [`MotorLink`]: one drive per joint on one bus (docs/canopen.md).
//!
//! - [`configure`] runs the start-up over SDO, before the control thread starts: every drive is
//!   told to disable its voltage first, then checked (device type, identity, CST support),
//!   mapped (RPDO1, TPDO1), put in CST, given its torque limit and its watchdogs; a drive that
//!   does not answer or refuses any step is named and nothing is enabled.
//! - [`CanopenLink`] runs the bus each control cycle: one RPDO1 per drive and a SYNC in
//!   [`MotorLink::send`], the drives' TPDO1s, heartbeats and emergencies in [`MotorLink::poll`].
//!   The daemon's motor currents map to ‰ of each drive's rated current (0x6075), which is ‰
//!   of its rated torque (0x6076): the daemon's torque constants stay the one unit conversion.
//!
//! Any fault (a fault statusword, an EMCY, a lost heartbeat, a node that reboots, bus errors, a
//! torque that is not a number) zeroes every torque, disables every axis and latches; telemetry
//! reports it as a fault bit, so that the cycle latches too. Only the operator's reset (the
//! first CLEAR_FAULT after another command) clears it, with one fault-reset edge per drive in
//! fault (sent again only if the bus refused its frame).
//! Missed TPDOs are missing telemetry: the cycle's link timeout latches them.

use std::time::{Duration, Instant};

use super::can::{CanBus, CanFrame};
use super::canopen::{
    heartbeat, map_pdo, nmt, sdo_reply, sync, Emergency, ErrorClass, NmtCommand, NmtState, NodeId, Object, SdoError,
    SdoReply, SdoRequest, HEARTBEAT_BASE, RPDO1_BASE, TPDO1_BASE,
};
use super::cia402::{controlword, rpdo1, Axis, AxisFault, RatedScale, Tpdo1};
use super::frame::{drive_fault, status, Command, Telemetry, MAX_JOINTS};
use super::{LinkStats, MotorLink};

/// How the frames reach the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Transport {
    /// A Lawicel (slcan) USB adapter on `link.port`.
    Slcan,
    /// A Linux SocketCAN interface, `link.interface`.
    Socketcan,
}

/// What a drive does when the master's heartbeat stops (object 0x6007).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AbortOption {
    QuickStop,
    DisableVoltage,
}

impl AbortOption {
    /// The value of 0x6007 (CiA 402: 2 disable voltage, 3 quick stop).
    pub fn value(self) -> u32 {
        match self {
            Self::DisableVoltage => 2,
            Self::QuickStop => 3,
        }
    }
}

/// The `[canopen]` table of the daemon's configuration. The SYNC period is the control period
/// (`control.rate_hz`): one SYNC per cycle.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CanopenConfig {
    pub transport: Transport,
    /// The drives' node IDs, one per joint in joint order.
    pub nodes: Vec<NodeId>,
    /// The master's own node ID: the COB-ID of its heartbeat, which every drive watches.
    pub master_node: NodeId,
    /// The bus's bit rate (bit/s); set on an slcan adapter, a SocketCAN interface's own.
    pub bit_rate: u32,
    /// Each drive's heartbeat period (0x1017).
    pub heartbeat_ms: u16,
    /// A drive whose heartbeat is missing this long latches a fault.
    pub heartbeat_timeout_ms: u16,
    /// The master's heartbeat period.
    pub master_heartbeat_ms: u16,
    /// A drive that misses the master's heartbeat this long aborts the connection (0x1016).
    pub master_heartbeat_timeout_ms: u16,
    /// The drives' reaction to it (0x6007).
    pub abort_connection: AbortOption,
    /// Each drive's torque limit, ‰ of its rated torque (0x6072).
    pub max_torque_permille: u16,
    /// How long a drive has to answer one SDO request at start-up.
    pub sdo_timeout_ms: u32,
}

/// ARASH:ASiST's three drives at node IDs 1–3. The heartbeat timeouts are three periods: a
/// heartbeat late by two periods is lost, not late.
impl Default for CanopenConfig {
    fn default() -> Self {
        let node = |id| NodeId::try_from(id).expect("a node ID in 1–127");
        Self {
            transport: Transport::Slcan,
            nodes: vec![node(1), node(2), node(3)],
            master_node: node(127),
            bit_rate: 1_000_000,
            heartbeat_ms: 50,
            heartbeat_timeout_ms: 150,
            master_heartbeat_ms: 50,
            master_heartbeat_timeout_ms: 150,
            abort_connection: AbortOption::QuickStop,
            max_torque_permille: 1000,
            sdo_timeout_ms: 200,
        }
    }
}

/// A `[canopen]` table that cannot work, named by its key.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CanopenConfigError {
    #[error("canopen.nodes has {got} node IDs; the robot has {dof} joints")]
    Count { got: usize, dof: usize },
    #[error("canopen.nodes: {node} is given twice (joints {first} and {second}); node IDs on one bus must differ")]
    Clash { node: NodeId, first: usize, second: usize },
    #[error("canopen.master_node: {0} is also a drive's node ID")]
    MasterClash(NodeId),
    #[error("canopen.{key} must be positive")]
    Zero { key: &'static str },
    #[error("canopen.{timeout} ({timeout_ms} ms) must be longer than canopen.{period} ({period_ms} ms)")]
    Timeout { timeout: &'static str, timeout_ms: u16, period: &'static str, period_ms: u16 },
}

impl CanopenConfig {
    pub fn validate(&self, dof: usize) -> Result<(), CanopenConfigError> {
        if self.nodes.len() != dof {
            return Err(CanopenConfigError::Count { got: self.nodes.len(), dof });
        }
        for (second, node) in self.nodes.iter().enumerate() {
            if let Some(first) = self.nodes[..second].iter().position(|n| n == node) {
                return Err(CanopenConfigError::Clash { node: *node, first, second });
            }
        }
        if self.nodes.contains(&self.master_node) {
            return Err(CanopenConfigError::MasterClash(self.master_node));
        }
        let positive = [
            ("bit_rate", self.bit_rate),
            ("heartbeat_ms", u32::from(self.heartbeat_ms)),
            ("master_heartbeat_ms", u32::from(self.master_heartbeat_ms)),
            ("max_torque_permille", u32::from(self.max_torque_permille)),
            ("sdo_timeout_ms", self.sdo_timeout_ms),
        ];
        if let Some((key, _)) = positive.iter().find(|(_, v)| *v == 0) {
            return Err(CanopenConfigError::Zero { key });
        }
        for (timeout, timeout_ms, period, period_ms) in [
            ("heartbeat_timeout_ms", self.heartbeat_timeout_ms, "heartbeat_ms", self.heartbeat_ms),
            (
                "master_heartbeat_timeout_ms",
                self.master_heartbeat_timeout_ms,
                "master_heartbeat_ms",
                self.master_heartbeat_ms,
            ),
        ] {
            if timeout_ms <= period_ms {
                return Err(CanopenConfigError::Timeout { timeout, timeout_ms, period, period_ms });
            }
        }
        Ok(())
    }
}

/// Why the start-up refused the drives. Each names the node, and nothing was enabled.
#[derive(Debug, thiserror::Error)]
pub enum StartupError {
    #[error(transparent)]
    Sdo(#[from] SdoError),
    #[error("{node} is not a CiA 402 drive: its device type (0x1000) is {value:#010x}, whose low 16 bits are not 402")]
    NotCia402 { node: NodeId, value: u32 },
    #[error("{node} does not offer cyclic synchronous torque mode: its supported drive modes (0x6502) are {value:#010x}, without bit 9")]
    NoCst { node: NodeId, value: u32 },
    #[error("{node} was set to cyclic synchronous torque mode (0x6060 = 10) but reports mode {shown} (0x6061)")]
    ModeIgnored { node: NodeId, shown: i8 },
    #[error("{node} reports a rated {what} of zero ({object}): its torque targets would have no scale")]
    NoRating { node: NodeId, what: &'static str, object: Object },
    #[error("{node} sent no heartbeat in operational state within {wait_ms} ms of its NMT start")]
    NotStarted { node: NodeId, wait_ms: u64 },
    #[error(
        "{node}: {answers} devices answer as this node (one read of 0x1018:4, answered {answers} times): give each drive \
         its own node ID (docs/canopen.md, \"Node IDs\")"
    )]
    NodeClash { node: NodeId, answers: usize },
    #[error("the CAN bus: {0}")]
    Bus(std::io::Error),
}

/// One drive as the start-up found it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveInfo {
    pub node: NodeId,
    /// 0x1018:1 and 0x1018:2.
    pub vendor: u32,
    pub product: u32,
    /// 0x6075, mA.
    pub rated_current_ma: u32,
    /// 0x6076, mN·m.
    pub rated_torque_mnm: u32,
    /// 0x6041 when the start-up ended.
    pub statusword: u16,
}

impl std::fmt::Display for DriveInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: vendor {:#010x}, product {:#010x}, rated {} mA, {} mN·m, statusword {:#06x}",
            self.node, self.vendor, self.product, self.rated_current_ma, self.rated_torque_mnm, self.statusword
        )
    }
}

/// Objects of the start-up, in CiA 301 and 402.
mod od {
    use super::Object;
    const fn o(index: u16, sub: u8) -> Object {
        Object { index, sub }
    }
    pub const DEVICE_TYPE: Object = o(0x1000, 0);
    pub const VENDOR: Object = o(0x1018, 1);
    pub const PRODUCT: Object = o(0x1018, 2);
    pub const SERIAL: Object = o(0x1018, 4);
    pub const SYNC_PERIOD: Object = o(0x1006, 0);
    pub const CONSUMER_HEARTBEAT: Object = o(0x1016, 1);
    pub const PRODUCER_HEARTBEAT: Object = o(0x1017, 0);
    pub const ABORT_CONNECTION: Object = o(0x6007, 0);
    pub const CONTROLWORD: Object = o(0x6040, 0);
    pub const STATUSWORD: Object = o(0x6041, 0);
    pub const MODE: Object = o(0x6060, 0);
    pub const MODE_DISPLAY: Object = o(0x6061, 0);
    pub const POSITION: Object = o(0x6064, 0);
    pub const TARGET_TORQUE: Object = o(0x6071, 0);
    pub const MAX_TORQUE: Object = o(0x6072, 0);
    pub const RATED_CURRENT: Object = o(0x6075, 0);
    pub const RATED_TORQUE: Object = o(0x6076, 0);
    pub const TORQUE_ACTUAL: Object = o(0x6077, 0);
    pub const SUPPORTED_MODES: Object = o(0x6502, 0);
}

/// CiA 402's device type in the low 16 bits of 0x1000.
const CIA402: u32 = 402;
/// Cyclic synchronous torque mode (0x6060).
const CST: u32 = 10;
/// Its bit in 0x6502.
const CST_SUPPORTED: u32 = 1 << 9;

/// The process data each drive is mapped with.
pub const RPDO1_MAP: [(Object, u8); 2] = [(od::CONTROLWORD, 16), (od::TARGET_TORQUE, 16)];
pub const TPDO1_MAP: [(Object, u8); 3] = [(od::STATUSWORD, 16), (od::POSITION, 32), (od::TORQUE_ACTUAL, 16)];

/// One expedited SDO transfer: send `request` to `node` and wait up to `timeout` for its answer,
/// dropping whatever else the bus carries meanwhile.
pub fn transfer<B: CanBus>(
    bus: &mut B,
    node: NodeId,
    request: SdoRequest,
    timeout: Duration,
) -> Result<SdoReply, StartupError> {
    Ok(exchange(bus, node, request, timeout, Duration::ZERO)?.0?)
}

/// How long the master listens for more answers after the first to one request at start-up: a
/// second device at the same node ID answers within its own SDO latency, a millisecond or two.
const CLASH_LISTEN: Duration = Duration::from_millis(20);

/// How many devices answer as `node`: one read of `object` (the serial number, 0x1018:4, which
/// differs between two devices, so that both answers reach the bus), the answers counted for
/// [`CLASH_LISTEN`] after the first. An abort counts as an answer. Two answers of the same bits
/// merge on a real bus into one and are not seen.
fn answers_to<B: CanBus>(bus: &mut B, node: NodeId, object: Object, timeout: Duration) -> Result<usize, StartupError> {
    Ok(exchange(bus, node, SdoRequest::Read(object), timeout, CLASH_LISTEN)?.1)
}

/// Send `request` to `node`, wait up to `timeout` for the first answer, then listen `listen`
/// longer: the first answer and how many came.
fn exchange<B: CanBus>(
    bus: &mut B,
    node: NodeId,
    request: SdoRequest,
    timeout: Duration,
    listen: Duration,
) -> Result<(Result<SdoReply, SdoError>, usize), StartupError> {
    bus.send(&request.frame(node)).map_err(StartupError::Bus)?;
    let deadline = Instant::now() + timeout;
    let mut first = None;
    let mut answers = 0;
    let mut listen_until = deadline;
    loop {
        while let Some(frame) = bus.receive().map_err(StartupError::Bus)? {
            if let Some(answer) = sdo_reply(&frame, node, &request) {
                if first.is_none() {
                    first = Some(answer);
                    listen_until = Instant::now() + listen;
                }
                answers += 1;
            }
        }
        // Without an answer `listen_until` is the deadline.
        if Instant::now() >= listen_until {
            return match first.take() {
                Some(answer) => Ok((answer, answers)),
                None => {
                    let timeout_ms = timeout.as_millis().min(u128::from(u32::MAX)) as u32;
                    Err(SdoError::Timeout { node, object: request.object(), timeout_ms }.into())
                }
            };
        }
        std::thread::sleep(Duration::from_micros(200));
    }
}

/// Configure every drive of `config` for CST at `sync_period`, in pre-operational, and start
/// them (NMT start). Returns what each drive reported, in joint order.
pub fn configure<B: CanBus>(
    bus: &mut B,
    config: &CanopenConfig,
    sync_period: Duration,
) -> Result<Vec<DriveInfo>, StartupError> {
    bus.send(&nmt(NmtCommand::EnterPreOperational, None)).map_err(StartupError::Bus)?;
    let drives = config
        .nodes
        .iter()
        .map(|&node| configure_drive(bus, node, config, sync_period))
        .collect::<Result<Vec<_>, _>>()?;
    for &node in &config.nodes {
        bus.send(&nmt(NmtCommand::Start, Some(node))).map_err(StartupError::Bus)?;
    }
    await_operational(bus, config)?;
    Ok(drives)
}

/// Wait until every drive's heartbeat reports it operational, for up to three of its periods.
/// The master's own heartbeat starts with the first control cycle: the drives' watch on it
/// (0x1016) starts with its first beat, so that the time until the control thread runs does not
/// count against it.
fn await_operational<B: CanBus>(bus: &mut B, config: &CanopenConfig) -> Result<(), StartupError> {
    let wait = Duration::from_millis(3 * u64::from(config.heartbeat_ms));
    let deadline = Instant::now() + wait;
    let mut waiting: Vec<NodeId> = config.nodes.clone();
    while !waiting.is_empty() {
        while let Some(frame) = bus.receive().map_err(StartupError::Bus)? {
            if let Some((node, NmtState::Operational)) = heartbeat(&frame) {
                waiting.retain(|n| *n != node);
            }
        }
        if Instant::now() >= deadline {
            return Err(StartupError::NotStarted { node: waiting[0], wait_ms: wait.as_millis() as u64 });
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    Ok(())
}

fn configure_drive<B: CanBus>(
    bus: &mut B,
    node: NodeId,
    config: &CanopenConfig,
    sync_period: Duration,
) -> Result<DriveInfo, StartupError> {
    let timeout = Duration::from_millis(u64::from(config.sdo_timeout_ms));
    let read = |bus: &mut B, object| -> Result<u32, StartupError> {
        match transfer(bus, node, SdoRequest::Read(object), timeout)? {
            SdoReply::Read { value, .. } => Ok(value),
            SdoReply::Written => unreachable!("sdo_reply answers a read with a value"),
        }
    };
    let write = |bus: &mut B, object, value, size| -> Result<(), StartupError> {
        transfer(bus, node, SdoRequest::Write { object, value, size }, timeout).map(|_| ())
    };
    // A drive left enabled by a daemon that crashed is switched off before anything else.
    write(bus, od::CONTROLWORD, 0, 2)?;
    // Drives often leave the factory at the same node ID; two on one bus would both take every
    // command meant for one joint.
    let answers = answers_to(bus, node, od::SERIAL, timeout)?;
    if answers > 1 {
        return Err(StartupError::NodeClash { node, answers });
    }
    let device_type = read(bus, od::DEVICE_TYPE)?;
    if device_type & 0xFFFF != CIA402 {
        return Err(StartupError::NotCia402 { node, value: device_type });
    }
    let (vendor, product) = (read(bus, od::VENDOR)?, read(bus, od::PRODUCT)?);
    let modes = read(bus, od::SUPPORTED_MODES)?;
    if modes & CST_SUPPORTED == 0 {
        return Err(StartupError::NoCst { node, value: modes });
    }
    let pdos = [
        map_pdo(0x1400, 0x1600, RPDO1_BASE + u32::from(node.get()), &RPDO1_MAP),
        map_pdo(0x1800, 0x1A00, TPDO1_BASE + u32::from(node.get()), &TPDO1_MAP),
    ];
    for step in pdos.iter().flatten() {
        transfer(bus, node, *step, timeout)?;
    }
    write(bus, od::MODE, CST, 1)?;
    let shown = read(bus, od::MODE_DISPLAY)? as u8 as i8;
    if shown as u32 != CST {
        return Err(StartupError::ModeIgnored { node, shown });
    }
    let rated_current_ma = read(bus, od::RATED_CURRENT)?;
    if rated_current_ma == 0 {
        return Err(StartupError::NoRating { node, what: "current", object: od::RATED_CURRENT });
    }
    let rated_torque_mnm = read(bus, od::RATED_TORQUE)?;
    if rated_torque_mnm == 0 {
        return Err(StartupError::NoRating { node, what: "torque", object: od::RATED_TORQUE });
    }
    write(bus, od::MAX_TORQUE, u32::from(config.max_torque_permille), 2)?;
    let period_us = sync_period.as_micros().min(u128::from(u32::MAX)) as u32;
    write(bus, od::SYNC_PERIOD, period_us, 4)?;
    write(bus, od::PRODUCER_HEARTBEAT, u32::from(config.heartbeat_ms), 2)?;
    let consumer = u32::from(config.master_node.get()) << 16 | u32::from(config.master_heartbeat_timeout_ms);
    write(bus, od::CONSUMER_HEARTBEAT, consumer, 4)?;
    write(bus, od::ABORT_CONNECTION, config.abort_connection.value(), 2)?;
    let statusword = read(bus, od::STATUSWORD)? as u16;
    Ok(DriveInfo { node, vendor, product, rated_current_ma, rated_torque_mnm, statusword })
}

/// Why the master latched its drives off; reported in telemetry as drive fault bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MasterFault {
    /// A drive's statusword reported a fault.
    Drive(NodeId),
    Emergency {
        node: NodeId,
        code: u16,
    },
    HeartbeatLost(NodeId),
    /// A drive left the operational state (a reboot, or another master's NMT command).
    NotOperational(NodeId),
    /// The CAN controller or adapter reported errors (bus-off, refused frames).
    Bus,
    /// The daemon asked for a torque that is not a number.
    NotFinite,
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
            Self::Drive(_) | Self::NotFinite => drive_fault::DRIVE,
            Self::HeartbeatLost(_) | Self::NotOperational(_) | Self::Bus => drive_fault::FIELDBUS,
        }
    }
}

/// SYNCs whose times are kept: far more than the sets in flight on a bus at 1 kHz.
const SYNC_RING: usize = 64;

/// The drives of [`configure`], run once per control cycle.
pub struct CanopenLink<B> {
    bus: B,
    nodes: [Option<NodeId>; MAX_JOINTS],
    joints: usize,
    axes: [Axis; MAX_JOINTS],
    /// Each drive's currents in ‰ of its rated current (0x6075), limited to 0x6072.
    scales: [Option<RatedScale>; MAX_JOINTS],
    last_heartbeat: [Instant; MAX_JOINTS],
    heartbeat_timeout: Duration,
    master_heartbeat: CanFrame,
    master_period: Duration,
    master_sent: Instant,
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
    bus_errors: u64,
    latched: Option<MasterFault>,
    /// The last command was CLEAR_FAULT: the operator's reset is under way.
    clearing: bool,
    stats: LinkStats,
}

impl<B: CanBus> CanopenLink<B> {
    /// The link over drives that [`configure`] has set up (and started).
    pub fn new(bus: B, config: &CanopenConfig, drives: &[DriveInfo]) -> Self {
        assert!(drives.len() <= MAX_JOINTS && drives.len() == config.nodes.len());
        let now = Instant::now();
        let mut nodes = [None; MAX_JOINTS];
        let mut scales = [None; MAX_JOINTS];
        for (j, d) in drives.iter().enumerate() {
            nodes[j] = Some(d.node);
            scales[j] = RatedScale::new(d.rated_current_ma, config.max_torque_permille);
            assert!(scales[j].is_some(), "configure refuses a drive rated for no current");
        }
        let bus_errors = bus.errors();
        Self {
            bus,
            nodes,
            joints: drives.len(),
            axes: [Axis::default(); MAX_JOINTS],
            scales,
            last_heartbeat: [now; MAX_JOINTS],
            heartbeat_timeout: Duration::from_millis(u64::from(config.heartbeat_timeout_ms)),
            master_heartbeat: CanFrame {
                id: HEARTBEAT_BASE + u32::from(config.master_node.get()),
                len: 1,
                data: [0x05, 0, 0, 0, 0, 0, 0, 0],
            },
            master_period: Duration::from_millis(u64::from(config.master_heartbeat_ms)),
            // The first cycle sends the master's first heartbeat.
            master_sent: now.checked_sub(Duration::from_secs(1)).unwrap_or(now),
            partial: Telemetry::new(drives.len()),
            have: 0,
            sets: 0,
            zero: [0; MAX_JOINTS],
            opened: now,
            sync_times: [0; SYNC_RING],
            syncs_sent: 0,
            answered: 0,
            bus_errors,
            latched: None,
            clearing: false,
            stats: LinkStats::default(),
        }
    }

    /// The fault the master latched, if any.
    pub fn latched(&self) -> Option<MasterFault> {
        self.latched
    }

    /// Latch every axis off for `fault`; the first fault is the one kept.
    fn latch(&mut self, fault: MasterFault) {
        self.latched.get_or_insert(fault);
        for axis in &mut self.axes[..self.joints] {
            axis.latch(AxisFault::Master);
        }
    }

    fn joint_of(&self, node: NodeId) -> Option<usize> {
        self.nodes[..self.joints].iter().position(|n| *n == Some(node))
    }

    /// The operator's reset: clear the latch, send each drive in fault one reset edge, and give
    /// the heartbeats a fresh timeout.
    fn reset(&mut self) {
        self.latched = None;
        self.bus_errors = self.bus.errors();
        let now = Instant::now();
        for j in 0..self.joints {
            self.axes[j].reset();
            self.last_heartbeat[j] = now;
        }
    }

    /// The target torque of joint `j` for `amps`, zero unless its axis may have one.
    fn permille(&mut self, j: usize, amps: f32) -> i16 {
        match self.scale(j).permille(f64::from(amps)) {
            Err(_) => {
                self.latch(MasterFault::NotFinite);
                0
            }
            Ok(_) if !self.axes[j].torque_allowed() => 0,
            Ok(permille) => permille,
        }
    }

    fn scale(&self, j: usize) -> RatedScale {
        self.scales[j].expect("a scale per joint")
    }

    fn send_frame(&mut self, frame: &CanFrame) -> std::io::Result<()> {
        self.bus.send(frame).inspect_err(|_| self.stats.send_errors += 1)
    }

    /// Fold one TPDO1 into this SYNC's set; `true` completes it.
    fn absorb(&mut self, j: usize, pdo: &Tpdo1) -> bool {
        self.axes[j].observe(pdo.statusword);
        if self.axes[j].latched().is_some() && self.latched.is_none() {
            self.latch(MasterFault::Drive(pdo.node));
        }
        if self.have & (1 << j) != 0 {
            // The last set never completed: a TPDO was missed.
            self.stats.lost += 1;
            self.have = 0;
            self.answered = self.answered.wrapping_add(1);
        }
        self.partial.counts[j] = pdo.position.wrapping_sub(self.zero[j]);
        self.partial.amps[j] = self.scale(j).value(pdo.torque_permille) as f32;
        self.have |= 1 << j;
        self.have == (1 << self.joints) - 1
    }

    fn on_frame(&mut self, frame: &CanFrame, out: &mut Telemetry) -> bool {
        if let Some(pdo) = Tpdo1::parse(frame) {
            if let Some(j) = self.joint_of(pdo.node) {
                if self.absorb(j, &pdo) {
                    self.have = 0;
                    self.sets = self.sets.wrapping_add(1);
                    self.finish(out);
                    return true;
                }
                return false;
            }
        }
        if let Some(emcy) = Emergency::parse(frame) {
            if self.joint_of(emcy.node).is_some() && emcy.is_error() {
                self.latch(MasterFault::Emergency { node: emcy.node, code: emcy.code });
            }
            return false;
        }
        if let Some((node, state)) = heartbeat(frame) {
            if let Some(j) = self.joint_of(node) {
                self.last_heartbeat[j] = Instant::now();
                if state != NmtState::Operational {
                    self.latch(MasterFault::NotOperational(node));
                }
            }
            return false;
        }
        // Other traffic on a shared bus is harmless; what the bus could not read is counted.
        self.stats.framing_errors += u64::from(frame.id == u32::MAX);
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
        let enabled = self.axes[..self.joints].iter().all(|a| a.state() == super::cia402::State::OperationEnabled);
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

    fn check_watchdogs(&mut self) {
        let now = Instant::now();
        for j in 0..self.joints {
            if now.duration_since(self.last_heartbeat[j]) > self.heartbeat_timeout {
                let node = self.nodes[j].expect("a node per joint");
                self.latch(MasterFault::HeartbeatLost(node));
            }
        }
        if self.bus.errors() != self.bus_errors {
            self.latch(MasterFault::Bus);
        }
    }
}

impl<B: CanBus> MotorLink for CanopenLink<B> {
    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        let clearing = matches!(command, Command::ClearFault);
        if clearing && !self.clearing {
            self.reset();
        }
        self.clearing = clearing;
        match command {
            Command::Enable => {
                for axis in &mut self.axes[..self.joints] {
                    // A latched axis stays off: the telemetry's fault bit tells the cycle.
                    let _ = axis.enable();
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
            let sent = self.send_frame(&rpdo1(self.nodes[j].expect("a node per joint"), word, torque));
            if sent.is_err() && word & controlword::FAULT_RESET != 0 {
                // A refused frame never reached the bus: the edge goes again.
                self.axes[j].edge_lost();
            }
            result = result.and(sent);
        }
        let now = Instant::now();
        self.sync_times[self.syncs_sent as usize % SYNC_RING] = now.duration_since(self.opened).as_micros() as u32;
        self.syncs_sent = self.syncs_sent.wrapping_add(1);
        result = result.and(self.send_frame(&sync()));
        if now.duration_since(self.master_sent) >= self.master_period {
            self.master_sent = now;
            let beat = self.master_heartbeat;
            result = result.and(self.send_frame(&beat));
        }
        self.stats.frames_sent += 1;
        result
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        let mut fresh = false;
        while let Some(frame) = self.bus.receive()? {
            fresh |= self.on_frame(&frame, out);
        }
        self.check_watchdogs();
        if fresh {
            // After every frame and watchdog of this poll: a fault found after the set completed
            // is reported with it.
            out.faults = self.fault_bits();
        }
        Ok(fresh)
    }

    fn stats(&self) -> LinkStats {
        self.stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::can::InProcessBus;
    use crate::link::canopen::SDO_REPLY_BASE;

    /// An expedited upload answer of 0x1018:4 from `node` (CiA 301: command 0x43, four bytes).
    fn serial_answer(node: NodeId, serial: u32) -> CanFrame {
        let [a, b, c, d] = serial.to_le_bytes();
        CanFrame { id: SDO_REPLY_BASE + u32::from(node.get()), len: 8, data: [0x43, 0x18, 0x10, 4, a, b, c, d] }
    }

    fn answers(serials: &[u32]) -> Result<usize, StartupError> {
        let node = NodeId::try_from(2).unwrap();
        let (mut host, mut drives) = InProcessBus::pair(16);
        for &s in serials {
            drives.send(&serial_answer(node, s)).unwrap();
        }
        answers_to(&mut host, node, od::SERIAL, Duration::from_millis(50))
    }

    #[test]
    fn every_device_that_answers_as_a_node_is_counted() {
        assert_eq!(answers(&[7]).unwrap(), 1);
        assert_eq!(answers(&[7, 9]).unwrap(), 2);
        assert!(matches!(answers(&[]), Err(StartupError::Sdo(SdoError::Timeout { .. }))));
    }
}
