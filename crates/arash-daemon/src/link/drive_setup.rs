//! A CiA 402 drive's start-up over SDO, as a sequence the master can run two ways: blocking,
//! before the control thread's first cycle ([`run`]), and one step per cycle inside it, when the
//! operator's reset brings back a drive that rebooted or left operational ([`DriveSetup`] is
//! sans-I/O: frames in, frames out, the time given).
//!
//! The sequence, per drive (docs/canopen.md, "What the daemon does at start-up"):
//!
//! 1. disable voltage (0x6040 := 0), first of all;
//! 2. one device per node ID (0x1018:4 read, answers counted for [`CLASH_LISTEN`]);
//! 3. the checks: device type 402 (0x1000), identity (0x1018:1, 2), CST offered (0x6502);
//! 4. the process data: RPDO1 and TPDO1 mapped, every SYNC;
//! 5. the mode: 0x6060 := 10, read back from 0x6061;
//! 6. the ratings (0x6075, 0x6076, neither zero) and the torque limit (0x6072);
//! 7. the watchdogs: SYNC period (0x1006), the drive's heartbeat (0x1017), the reaction to a
//!    lost master (0x6007) and, last, the watch on the master's heartbeat (0x1016);
//! 8. the statusword read, then NMT start and the drive's heartbeat in operational.
//!
//! The master's heartbeat goes out every period from the first step on ([`MasterHeartbeat`]):
//! a drive's watch on it (0x1016) starts with the first beat it sees, and from then on the beats
//! never stop, however long the start-up takes.

use std::time::{Duration, Instant};

use super::can::{CanBus, CanFrame};
use super::canopen::{
    heartbeat, map_pdo, nmt, sdo_reply, NmtCommand, NmtState, NodeId, Object, SdoError, SdoReply, SdoRequest,
    HEARTBEAT_BASE, RPDO1_BASE, TPDO1_BASE,
};

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

/// Why a drive's start-up failed. Each names the node, and the drive was not enabled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SetupError {
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
}

/// Why the start-up refused the drives: a drive's own refusal, or the bus.
#[derive(Debug, thiserror::Error)]
pub enum StartupError {
    #[error(transparent)]
    Drive(#[from] SetupError),
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

/// How long the master listens for more answers after the first to the serial-number read: a
/// second device at the same node ID answers within its own SDO latency, a millisecond or two.
pub const CLASH_LISTEN: Duration = Duration::from_millis(20);

/// What a step does with its answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Check {
    /// A write that the drive acknowledged.
    Written,
    /// Every device that answers as the node is counted (two at one node ID answer twice).
    OneDevice,
    DeviceType,
    Vendor,
    Product,
    Modes,
    ModeShown,
    RatedCurrent,
    RatedTorque,
    Statusword,
}

#[derive(Debug, Clone, Copy)]
struct Step {
    request: SdoRequest,
    check: Check,
}

/// The longest sequence: 31 steps with the mappings above.
const MAX_STEPS: usize = 32;

/// Which part of the sequence a [`DriveSetup`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// Disable voltage only: what the master does to every drive as soon as the bus is open.
    Disable,
    /// Everything after it, then NMT start: the start-up proper.
    Configure,
    /// All of it: a drive that rebooted or left operational, brought back on the operator's reset.
    Recover,
}

/// One drive's start-up, driven without I/O: [`DriveSetup::poll`] says what to send or how it
/// ended, [`DriveSetup::on_frame`] takes what the bus carried. No allocation: the recovery of a
/// drive runs inside the control cycle.
#[derive(Debug, Clone)]
pub struct DriveSetup {
    node: NodeId,
    steps: [Step; MAX_STEPS],
    at: usize,
    end: usize,
    /// The request of step `at`, when it went out, and what has answered it.
    sent: Option<Sent>,
    starts: bool,
    phase: Phase,
    sdo_timeout: Duration,
    start_wait: Duration,
    info: DriveInfo,
}

#[derive(Debug, Clone, Copy)]
struct Sent {
    at: Instant,
    first: Option<(Instant, Result<SdoReply, SdoError>)>,
    answers: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Transfers,
    /// NMT start sent; waiting for the drive's heartbeat in operational until the deadline.
    Starting {
        deadline: Instant,
    },
    Done,
    Failed(SetupError),
}

/// What a [`DriveSetup`] wants now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SetupPoll {
    /// Put this frame on the bus.
    Send(CanFrame),
    /// Waiting for an answer, or for leave to send NMT start.
    Busy,
    Done(DriveInfo),
    Failed(SetupError),
}

impl DriveSetup {
    pub fn new(node: NodeId, config: &CanopenConfig, sync_period: Duration, scope: Scope) -> Self {
        let (steps, len) = sequence(node, config, sync_period);
        let (at, end) = match scope {
            Scope::Disable => (0, 1),
            Scope::Configure => (1, len),
            Scope::Recover => (0, len),
        };
        Self {
            node,
            steps,
            at,
            end,
            sent: None,
            starts: scope != Scope::Disable,
            phase: Phase::Transfers,
            sdo_timeout: Duration::from_millis(u64::from(config.sdo_timeout_ms)),
            // Three of the drive's heartbeat periods: a heartbeat late by two is lost, not late.
            start_wait: Duration::from_millis(3 * u64::from(config.heartbeat_ms)),
            info: DriveInfo { node, vendor: 0, product: 0, rated_current_ma: 0, rated_torque_mnm: 0, statusword: 0 },
        }
    }

    pub fn node(&self) -> NodeId {
        self.node
    }

    /// Every transfer done: only NMT start (if this scope sends it) is left.
    pub fn ready_to_start(&self) -> bool {
        self.phase != Phase::Transfers || self.at == self.end
    }

    /// Take a frame from the bus: the answer to the transfer under way, or the drive's
    /// heartbeat after its NMT start.
    pub fn on_frame(&mut self, frame: &CanFrame, now: Instant) {
        match self.phase {
            Phase::Transfers => {
                let (Some(sent), Some(step)) = (self.sent.as_mut(), self.steps.get(self.at)) else { return };
                if let Some(answer) = sdo_reply(frame, self.node, &step.request) {
                    sent.first.get_or_insert((now, answer));
                    sent.answers += 1;
                }
            }
            Phase::Starting { .. } => {
                if heartbeat(frame) == Some((self.node, NmtState::Operational)) {
                    self.phase = Phase::Done;
                }
            }
            Phase::Done | Phase::Failed(_) => {}
        }
    }

    /// What to do at `now`. `may_start`: whether NMT start may go out once the transfers are
    /// done (the start-up starts the drives together, after every one is configured).
    pub fn poll(&mut self, now: Instant, may_start: bool) -> SetupPoll {
        loop {
            match self.phase {
                Phase::Done => return SetupPoll::Done(self.info),
                Phase::Failed(e) => return SetupPoll::Failed(e),
                Phase::Starting { deadline } if now >= deadline => {
                    let wait_ms = self.start_wait.as_millis() as u64;
                    self.phase = Phase::Failed(SetupError::NotStarted { node: self.node, wait_ms });
                }
                Phase::Starting { .. } => return SetupPoll::Busy,
                Phase::Transfers if self.at == self.end => {
                    if !self.starts {
                        self.phase = Phase::Done;
                    } else if !may_start {
                        return SetupPoll::Busy;
                    } else {
                        self.phase = Phase::Starting { deadline: now + self.start_wait };
                        return SetupPoll::Send(nmt(NmtCommand::Start, Some(self.node)));
                    }
                }
                Phase::Transfers => match self.sent {
                    None => {
                        self.sent = Some(Sent { at: now, first: None, answers: 0 });
                        return SetupPoll::Send(self.steps[self.at].request.frame(self.node));
                    }
                    Some(sent) => match self.answered(sent, now) {
                        None => return SetupPoll::Busy,
                        Some(Ok(())) => {
                            self.at += 1;
                            self.sent = None;
                        }
                        Some(Err(e)) => self.phase = Phase::Failed(e),
                    },
                },
            }
        }
    }

    /// The outcome of the step under way at `now`, `None` while it waits.
    fn answered(&mut self, sent: Sent, now: Instant) -> Option<Result<(), SetupError>> {
        let step = self.steps[self.at];
        let listen = if step.check == Check::OneDevice { CLASH_LISTEN } else { Duration::ZERO };
        match sent.first {
            Some((first, answer)) if now >= first + listen => {
                Some(answer.map_err(SetupError::from).and_then(|reply| {
                    let value = match reply {
                        SdoReply::Read { value, .. } => value,
                        SdoReply::Written => 0,
                    };
                    self.check(step, value, sent.answers)
                }))
            }
            Some(_) => None,
            None if now >= sent.at + self.sdo_timeout => {
                let timeout_ms = self.sdo_timeout.as_millis().min(u128::from(u32::MAX)) as u32;
                Some(Err(SdoError::Timeout { node: self.node, object: step.request.object(), timeout_ms }.into()))
            }
            None => None,
        }
    }

    fn check(&mut self, step: Step, value: u32, answers: usize) -> Result<(), SetupError> {
        let node = self.node;
        let info = &mut self.info;
        match step.check {
            Check::Written => {}
            Check::OneDevice if answers > 1 => return Err(SetupError::NodeClash { node, answers }),
            Check::OneDevice => {}
            Check::DeviceType if value & 0xFFFF != CIA402 => return Err(SetupError::NotCia402 { node, value }),
            Check::DeviceType => {}
            Check::Vendor => info.vendor = value,
            Check::Product => info.product = value,
            Check::Modes if value & CST_SUPPORTED == 0 => return Err(SetupError::NoCst { node, value }),
            Check::Modes => {}
            Check::ModeShown if value as u8 as i8 as u32 != CST => {
                return Err(SetupError::ModeIgnored { node, shown: value as u8 as i8 })
            }
            Check::ModeShown => {}
            Check::RatedCurrent if value == 0 => {
                return Err(SetupError::NoRating { node, what: "current", object: od::RATED_CURRENT })
            }
            Check::RatedCurrent => info.rated_current_ma = value,
            Check::RatedTorque if value == 0 => {
                return Err(SetupError::NoRating { node, what: "torque", object: od::RATED_TORQUE })
            }
            Check::RatedTorque => info.rated_torque_mnm = value,
            Check::Statusword => info.statusword = value as u16,
        }
        Ok(())
    }
}

/// The whole sequence for `node`, in order (the module's list).
fn sequence(node: NodeId, config: &CanopenConfig, sync_period: Duration) -> ([Step; MAX_STEPS], usize) {
    let mut steps = [Step { request: SdoRequest::Read(od::STATUSWORD), check: Check::Written }; MAX_STEPS];
    let mut len = 0;
    let mut push = |request, check| {
        steps[len] = Step { request, check };
        len += 1;
    };
    let write = |object, value, size| SdoRequest::Write { object, value, size };
    push(write(od::CONTROLWORD, 0, 2), Check::Written);
    push(SdoRequest::Read(od::SERIAL), Check::OneDevice);
    push(SdoRequest::Read(od::DEVICE_TYPE), Check::DeviceType);
    push(SdoRequest::Read(od::VENDOR), Check::Vendor);
    push(SdoRequest::Read(od::PRODUCT), Check::Product);
    push(SdoRequest::Read(od::SUPPORTED_MODES), Check::Modes);
    for request in map_pdo(0x1400, 0x1600, RPDO1_BASE + u32::from(node.get()), &RPDO1_MAP).chain(map_pdo(
        0x1800,
        0x1A00,
        TPDO1_BASE + u32::from(node.get()),
        &TPDO1_MAP,
    )) {
        push(request, Check::Written);
    }
    push(write(od::MODE, CST, 1), Check::Written);
    push(SdoRequest::Read(od::MODE_DISPLAY), Check::ModeShown);
    push(SdoRequest::Read(od::RATED_CURRENT), Check::RatedCurrent);
    push(SdoRequest::Read(od::RATED_TORQUE), Check::RatedTorque);
    push(write(od::MAX_TORQUE, u32::from(config.max_torque_permille), 2), Check::Written);
    let period_us = sync_period.as_micros().min(u128::from(u32::MAX)) as u32;
    push(write(od::SYNC_PERIOD, period_us, 4), Check::Written);
    push(write(od::PRODUCER_HEARTBEAT, u32::from(config.heartbeat_ms), 2), Check::Written);
    // The reaction before the watch that triggers it.
    push(write(od::ABORT_CONNECTION, config.abort_connection.value(), 2), Check::Written);
    let consumer = u32::from(config.master_node.get()) << 16 | u32::from(config.master_heartbeat_timeout_ms);
    push(write(od::CONSUMER_HEARTBEAT, consumer, 4), Check::Written);
    push(SdoRequest::Read(od::STATUSWORD), Check::Statusword);
    (steps, len)
}

/// The master's heartbeat (its NMT state, operational, at `0x700 + master_node`), due every
/// `master_heartbeat_ms` from the first call on.
#[derive(Debug, Clone, Copy)]
pub struct MasterHeartbeat {
    frame: CanFrame,
    period: Duration,
    sent: Option<Instant>,
}

impl MasterHeartbeat {
    pub fn new(config: &CanopenConfig) -> Self {
        Self {
            frame: CanFrame {
                id: HEARTBEAT_BASE + u32::from(config.master_node.get()),
                len: 1,
                data: [0x05, 0, 0, 0, 0, 0, 0, 0],
            },
            period: Duration::from_millis(u64::from(config.master_heartbeat_ms)),
            sent: None,
        }
    }

    /// The heartbeat frame if one is due at `now` (counted as sent).
    pub fn due(&mut self, now: Instant) -> Option<CanFrame> {
        match self.sent {
            Some(sent) if now.duration_since(sent) < self.period => None,
            _ => {
                self.sent = Some(now);
                Some(self.frame)
            }
        }
    }
}

/// Run `setups` on `bus` to their end, together (each node has its own SDO channel), sending
/// the master's heartbeat when due if `beat` is given; NMT start goes out only once every
/// drive is configured. The drives' information in the order of `setups`, or the first
/// refusal.
pub fn run<B: CanBus>(
    bus: &mut B,
    setups: &mut [DriveSetup],
    mut beat: Option<&mut MasterHeartbeat>,
) -> Result<Vec<DriveInfo>, StartupError> {
    loop {
        let now = Instant::now();
        if let Some(frame) = beat.as_mut().and_then(|b| b.due(now)) {
            bus.send(&frame).map_err(StartupError::Bus)?;
        }
        bus.service().map_err(StartupError::Bus)?;
        while let Some(frame) = bus.receive().map_err(StartupError::Bus)? {
            setups.iter_mut().for_each(|s| s.on_frame(&frame, now));
        }
        let may_start = setups.iter().all(DriveSetup::ready_to_start);
        let mut done = Vec::with_capacity(setups.len());
        for setup in setups.iter_mut() {
            match setup.poll(now, may_start) {
                SetupPoll::Send(frame) => bus.send(&frame).map_err(StartupError::Bus)?,
                SetupPoll::Busy => {}
                SetupPoll::Done(info) => done.push(info),
                SetupPoll::Failed(e) => return Err(e.into()),
            }
        }
        if done.len() == setups.len() {
            return Ok(done);
        }
        std::thread::sleep(Duration::from_micros(200));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::can::InProcessBus;
    use crate::link::canopen::SDO_REPLY_BASE;

    fn node(id: u8) -> NodeId {
        NodeId::try_from(id).unwrap()
    }

    /// The drive's side of one expedited transfer (CiA 301): a read answered with four bytes
    /// (0x43), a write acknowledged (0x60).
    fn answer(node: NodeId, request: &CanFrame, value: u32) -> CanFrame {
        let d = request.data;
        let command = if d[0] == 0x40 { 0x43 } else { 0x60 };
        let [a, b, c, e] = value.to_le_bytes();
        CanFrame { id: SDO_REPLY_BASE + u32::from(node.get()), len: 8, data: [command, d[1], d[2], d[3], a, b, c, e] }
    }

    /// A conformant CST drive's value for each object the start-up reads.
    fn value_of(request: &CanFrame) -> u32 {
        match (u16::from_le_bytes([request.data[1], request.data[2]]), request.data[3]) {
            (0x1000, 0) => 0x0002_0192,
            (0x1018, 1) => 0xFB,
            (0x1018, 2) => 0x0040_2402,
            (0x1018, 4) => 7,
            (0x6502, 0) => 1 << 9,
            (0x6061, 0) => 10,
            (0x6075, 0) => 5000,
            (0x6076, 0) => 138,
            (0x6041, 0) => 0x0250,
            _ => 0,
        }
    }

    /// A recovery runs to its end one poll at a time, as the cycle runs it: every transfer of the
    /// sequence in order, the consumer heartbeat (0x1016) last, then NMT start and the drive's
    /// operational heartbeat.
    #[test]
    fn a_recovery_runs_the_whole_sequence_one_transfer_at_a_time() {
        let config = CanopenConfig::default();
        let n = node(2);
        let mut setup = DriveSetup::new(n, &config, Duration::from_millis(1), Scope::Recover);
        let mut now = Instant::now();
        let mut objects = Vec::new();
        let info = loop {
            match setup.poll(now, true) {
                SetupPoll::Send(frame) if frame.id == 0x602 => {
                    objects.push((u16::from_le_bytes([frame.data[1], frame.data[2]]), frame.data[3]));
                    assert_eq!(setup.poll(now, true), SetupPoll::Busy, "one transfer at a time");
                    setup.on_frame(&answer(n, &frame, value_of(&frame)), now);
                    now += CLASH_LISTEN;
                }
                SetupPoll::Send(frame) => {
                    assert_eq!((frame.id, &frame.data[..2]), (0x000, &[0x01, 0x02][..]), "NMT start");
                    setup.on_frame(&CanFrame { id: 0x702, len: 1, data: [0x7F, 0, 0, 0, 0, 0, 0, 0] }, now);
                    assert_eq!(setup.poll(now, true), SetupPoll::Busy, "pre-operational is not started");
                    setup.on_frame(&CanFrame { id: 0x702, len: 1, data: [0x05, 0, 0, 0, 0, 0, 0, 0] }, now);
                }
                SetupPoll::Done(info) => break info,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(objects.len(), 31);
        assert_eq!(objects[0], (0x6040, 0));
        assert_eq!(objects[objects.len() - 2], (0x1016, 1));
        assert_eq!((info.rated_current_ma, info.rated_torque_mnm, info.statusword), (5000, 138, 0x0250));
    }

    /// Every device that answers as the node is counted within the listening window; silence is a
    /// timeout that names the node and the object.
    #[test]
    fn every_device_that_answers_as_a_node_is_counted_and_silence_is_named() {
        let config = CanopenConfig::default();
        let n = node(2);
        let outcome = |serials: &[u32]| {
            let mut setup = DriveSetup::new(n, &config, Duration::from_millis(1), Scope::Configure);
            let t0 = Instant::now();
            let SetupPoll::Send(read) = setup.poll(t0, false) else { panic!("the serial-number read") };
            assert_eq!(&read.data[..4], &[0x40, 0x18, 0x10, 4]);
            for &s in serials {
                setup.on_frame(&answer(n, &read, s), t0);
            }
            let later = t0 + Duration::from_millis(u64::from(config.sdo_timeout_ms)) + CLASH_LISTEN;
            setup.poll(later, false)
        };
        assert!(matches!(outcome(&[7]), SetupPoll::Send(_)), "one device: on to the next step");
        assert_eq!(outcome(&[7, 9]), SetupPoll::Failed(SetupError::NodeClash { node: n, answers: 2 }));
        let SetupPoll::Failed(silent) = outcome(&[]) else { panic!() };
        assert_eq!(silent.to_string(), "node 2 did not answer the SDO transfer of 0x1018:4 within 200 ms");
    }

    /// The blocking start-up sends the master's heartbeat every period while it waits for a
    /// drive, and stops at a drive's refusal, naming it.
    #[test]
    fn the_blocking_start_up_beats_while_it_waits_and_names_a_refusal() {
        let config = CanopenConfig { master_heartbeat_ms: 5, sdo_timeout_ms: 40, ..CanopenConfig::default() };
        let (mut host, mut drive) = InProcessBus::pair(256);
        let mut setups = [DriveSetup::new(node(1), &config, Duration::from_millis(1), Scope::Configure)];
        let mut beat = MasterHeartbeat::new(&config);
        let e = run(&mut host, &mut setups, Some(&mut beat)).unwrap_err();
        assert!(e.to_string().contains("node 1 did not answer the SDO transfer of 0x1018:4 within 40 ms"), "{e}");
        let mut beats = 0;
        while let Ok(Some(frame)) = drive.receive() {
            beats += usize::from(frame.id == 0x77F && frame.data[0] == 0x05);
        }
        assert!((6..=10).contains(&beats), "{beats} heartbeats in 40 ms at 5 ms");
    }
}
