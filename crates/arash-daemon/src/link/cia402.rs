//! A CiA 402 drive axis in cyclic synchronous torque mode, as the master sees it: the
//! statusword's states, the controlword's commands, the process data of one SYNC cycle, and the
//! axis's own supervision, with faults that latch until the operator resets them. Sans-I/O:
//! statuswords in, controlwords and frames out.
//!
//! The process data:
//!
//! | PDO | COB-ID | content |
//! |---|---|---|
//! | RPDO1 | `0x200 + node` | 0x6040 controlword (u16), 0x6071 target torque (i16, ‰ of 0x6076) |
//! | TPDO1 | `0x180 + node` | 0x6041 statusword (u16), 0x6064 position (i32, counts), 0x6077 torque actual (i16, ‰) |

use super::can::CanFrame;
use super::canopen::{NodeId, RPDO1_BASE, TPDO1_BASE};

/// The states of the drive's power state machine (CiA 402, figure 8), read from the statusword.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    NotReadyToSwitchOn,
    SwitchOnDisabled,
    ReadyToSwitchOn,
    SwitchedOn,
    OperationEnabled,
    QuickStopActive,
    FaultReactionActive,
    Fault,
    /// A statusword that matches no state.
    Unknown(u16),
}

impl State {
    /// The state a statusword reports (CiA 402, table 30: bits 0–3, 5 and 6).
    pub fn of(statusword: u16) -> Self {
        match (statusword & 0x4F, statusword & 0x6F) {
            (0x00, _) => Self::NotReadyToSwitchOn,
            (0x40, _) => Self::SwitchOnDisabled,
            (_, 0x21) => Self::ReadyToSwitchOn,
            (_, 0x23) => Self::SwitchedOn,
            (_, 0x27) => Self::OperationEnabled,
            (_, 0x07) => Self::QuickStopActive,
            (0x0F, _) => Self::FaultReactionActive,
            (0x08, _) => Self::Fault,
            _ => Self::Unknown(statusword),
        }
    }

    pub fn is_fault(self) -> bool {
        matches!(self, Self::Fault | Self::FaultReactionActive)
    }

    /// Where the state stands on the master's walk to operation enabled (figure 8's
    /// transitions 2, 3 and 4): `None` for the states the master never commands.
    fn walk(self) -> Option<u8> {
        match self {
            Self::SwitchOnDisabled => Some(0),
            Self::ReadyToSwitchOn => Some(1),
            Self::SwitchedOn => Some(2),
            Self::OperationEnabled => Some(3),
            _ => None,
        }
    }
}

impl std::fmt::Display for State {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotReadyToSwitchOn => f.write_str("not ready to switch on"),
            Self::SwitchOnDisabled => f.write_str("switch on disabled"),
            Self::ReadyToSwitchOn => f.write_str("ready to switch on"),
            Self::SwitchedOn => f.write_str("switched on"),
            Self::OperationEnabled => f.write_str("operation enabled"),
            Self::QuickStopActive => f.write_str("quick stop active"),
            Self::FaultReactionActive => f.write_str("fault reaction active"),
            Self::Fault => f.write_str("fault"),
            Self::Unknown(word) => write!(f, "no state (statusword {word:#06x})"),
        }
    }
}

/// Controlword commands (CiA 402, table 28).
pub mod controlword {
    pub const DISABLE_VOLTAGE: u16 = 0x0000;
    pub const QUICK_STOP: u16 = 0x0002;
    pub const SHUTDOWN: u16 = 0x0006;
    pub const SWITCH_ON: u16 = 0x0007;
    pub const ENABLE_OPERATION: u16 = 0x000F;
    /// Bit 7: a fault reset on its rising edge.
    pub const FAULT_RESET: u16 = 0x0080;
}

/// Statusword bit 12 in the cyclic synchronous modes: the drive follows the target.
pub const FOLLOWS_TARGET: u16 = 1 << 12;

/// The controlword that moves a drive in `state` one step towards operation enabled.
pub fn towards_enabled(state: State) -> u16 {
    match state {
        State::SwitchOnDisabled => controlword::SHUTDOWN,
        State::ReadyToSwitchOn => controlword::SWITCH_ON,
        State::SwitchedOn | State::OperationEnabled => controlword::ENABLE_OPERATION,
        // States the walk never leads to: an [`Axis`] latches in them, and the drive gets
        // disable voltage.
        State::QuickStopActive
        | State::NotReadyToSwitchOn
        | State::FaultReactionActive
        | State::Fault
        | State::Unknown(_) => controlword::DISABLE_VOLTAGE,
    }
}

/// A drive's torque in ‰ of its rating, limited to 0x6072. CiA 402 gives the target (0x6071) and
/// the actual torque (0x6077) in ‰ of the rated torque (0x6076), which is the torque at the
/// rated current (0x6075): the same ‰ scale a current in ‰ of the rated current, and the master
/// uses it so (the daemon commands currents).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RatedScale {
    /// The rating in the unit the value is given in: 0x6076 in N·m, or 0x6075 in A (the drive
    /// reports mN·m and mA).
    pub rated: f64,
    /// 0x6072, ‰ of the rating.
    pub max_permille: u16,
}

/// A torque or current that is not a number, refused before it reaches a drive.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("a torque or current of {0} is not finite")]
pub struct NotFinite(pub f64);

impl RatedScale {
    /// From a rating in thousandths of its unit (0x6076 in mN·m, 0x6075 in mA) and 0x6072 (‰).
    /// `None` when the rating is zero: every target would be zero or infinite.
    pub fn new(rated_milli: u32, max_permille: u16) -> Option<Self> {
        (rated_milli > 0).then(|| Self { rated: f64::from(rated_milli) / 1000.0, max_permille })
    }

    /// The target (0x6071) for `value`, saturated at ±0x6072.
    pub fn permille(&self, value: f64) -> Result<i16, NotFinite> {
        if !value.is_finite() {
            return Err(NotFinite(value));
        }
        let limit = f64::from(self.max_permille.min(i16::MAX as u16));
        Ok((1000.0 * value / self.rated).round().clamp(-limit, limit) as i16)
    }

    /// The value of a target or actual in ‰ (0x6077, torque actual).
    pub fn value(&self, permille: i16) -> f64 {
        f64::from(permille) * self.rated / 1000.0
    }
}

/// RPDO1 to `node`: controlword and target torque.
pub fn rpdo1(node: NodeId, controlword: u16, torque_permille: i16) -> CanFrame {
    let (c, t) = (controlword.to_le_bytes(), torque_permille.to_le_bytes());
    CanFrame { id: RPDO1_BASE + u32::from(node.get()), len: 4, data: [c[0], c[1], t[0], t[1], 0, 0, 0, 0] }
}

/// TPDO1 from a drive: statusword, position and torque actual.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tpdo1 {
    pub node: NodeId,
    pub statusword: u16,
    pub position: i32,
    pub torque_permille: i16,
}

impl Tpdo1 {
    /// `None` for any frame that is not an 8-byte TPDO1.
    pub fn parse(frame: &CanFrame) -> Option<Self> {
        let node = NodeId::of(frame, TPDO1_BASE)?;
        let d = frame.data;
        (frame.len == 8).then(|| Self {
            node,
            statusword: u16::from_le_bytes([d[0], d[1]]),
            position: i32::from_le_bytes([d[2], d[3], d[4], d[5]]),
            torque_permille: i16::from_le_bytes([d[6], d[7]]),
        })
    }

    /// The frame a drive sends for these values (the simulator's side, and the tests').
    pub fn frame(&self) -> CanFrame {
        let (s, p, t) =
            (self.statusword.to_le_bytes(), self.position.to_le_bytes(), self.torque_permille.to_le_bytes());
        CanFrame {
            id: TPDO1_BASE + u32::from(self.node.get()),
            len: 8,
            data: [s[0], s[1], p[0], p[1], p[2], p[3], t[0], t[1]],
        }
    }
}

/// Why an axis is latched off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisFault {
    /// The drive reported a fault in its statusword.
    Drive { statusword: u16 },
    /// The drive left the walk to operation enabled, or operation enabled itself, without the
    /// master commanding it: its quick-stop input, safe torque off, or any state the master
    /// did not ask for.
    Stopped { statusword: u16 },
    /// The master latched it: an EMCY, a lost heartbeat, missed TPDOs, an SDO abort, bus-off.
    Master,
}

/// The operator asked to enable an axis that is latched off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the axis is latched off ({0:?}): reset it first")]
pub struct Latched(pub AxisFault);

/// One axis's supervision: the state its drive last reported, whether the operator wants it
/// enabled, and a latched fault. A fault disables the axis and clears the operator's request, so
/// that nothing re-enables it by itself; a fault reset is sent only on the operator's [`reset`]
/// as one rising edge of bit 7.
///
/// While the operator wants it enabled, the drive may only move forward on the walk (switch on
/// disabled, ready to switch on, switched on, operation enabled), one step per controlword the
/// master sends, and stay in operation enabled once there. Any other state (a step back, quick
/// stop active, not ready to switch on, or a state the statusword does not name) is the drive
/// stopping by itself, and latches: walking it back would restart a machine that an e-stop or
/// safe torque off has stopped (IEC 60204-1, 9.2.5.4: restart only by a deliberate action).
///
/// [`reset`]: Axis::reset
#[derive(Debug, Clone, Copy)]
pub struct Axis {
    state: State,
    wanted: bool,
    /// The furthest step of the walk seen since the operator's enable (`None`: no statusword
    /// since it).
    progress: Option<u8>,
    latched: Option<AxisFault>,
    reset: ResetEdge,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ResetEdge {
    Idle,
    /// Send bit 7 low for a cycle, then high for one.
    Low,
    High,
    /// The edge was sent: the drive's fault does not latch again until it has left the fault
    /// (its statusword lags the controlword by a cycle or more).
    Sent,
}

impl Default for Axis {
    fn default() -> Self {
        Self { state: State::NotReadyToSwitchOn, wanted: false, progress: None, latched: None, reset: ResetEdge::Idle }
    }
}

impl Axis {
    pub fn state(&self) -> State {
        self.state
    }

    pub fn latched(&self) -> Option<AxisFault> {
        self.latched
    }

    /// The drive's statusword of this cycle. A fault latches, and so does a drive that stops
    /// by itself while the operator wants it enabled; only the operator's reset clears the
    /// latch: a drive that recovers by itself stays latched off.
    pub fn observe(&mut self, statusword: u16) {
        self.state = State::of(statusword);
        if self.reset == ResetEdge::Sent && !self.state.is_fault() {
            self.reset = ResetEdge::Idle;
        }
        if self.latched.is_some() || self.reset != ResetEdge::Idle {
            return;
        }
        if self.state.is_fault() {
            self.latch(AxisFault::Drive { statusword });
        } else if self.wanted && !self.walks_forward() {
            self.latch(AxisFault::Stopped { statusword });
        }
    }

    /// Whether the state just observed is one the master's walk may have led to: a step of the
    /// walk no earlier than the furthest seen since the enable (statuswords arrive in order, and
    /// a drive that has taken a step does not take it back unless told to).
    fn walks_forward(&mut self) -> bool {
        match (self.state.walk(), self.progress) {
            (Some(step), Some(furthest)) if step < furthest => false,
            (Some(step), _) => {
                self.progress = Some(step);
                true
            }
            (None, _) => false,
        }
    }

    /// Latch the axis off: disable it, and forget the operator's request.
    pub fn latch(&mut self, fault: AxisFault) {
        self.latched.get_or_insert(fault);
        self.wanted = false;
    }

    /// The operator's `enable`; refused while latched. The walk starts from the next statusword.
    pub fn enable(&mut self) -> Result<(), Latched> {
        match self.latched {
            Some(fault) => Err(Latched(fault)),
            None => {
                if !self.wanted {
                    self.wanted = true;
                    self.progress = None;
                }
                Ok(())
            }
        }
    }

    /// The operator's `disable`.
    pub fn disable(&mut self) {
        self.wanted = false;
    }

    /// Whether the operator wants the axis enabled.
    pub fn wanted(&self) -> bool {
        self.wanted
    }

    /// The operator's `reset`: clear the latch and, if the drive is in fault, send it one fault
    /// reset edge. The axis stays disabled until the operator enables it again.
    pub fn reset(&mut self) {
        self.wanted = false;
        self.latched = None;
        if self.state.is_fault() {
            self.reset = ResetEdge::Low;
        }
    }

    /// The frame that carried this axis's fault-reset edge was refused by the bus: send the
    /// edge again (low for a cycle, then high).
    pub fn edge_lost(&mut self) {
        if self.reset == ResetEdge::Sent {
            self.reset = ResetEdge::Low;
        }
    }

    /// Whether the drive may be given a torque this cycle: enabled, or being enabled by this
    /// cycle's controlword. The target travels with "enable operation", so that a joint under
    /// gravity is held from the first SYNC its drive is enabled at, not one round trip later
    /// (a drive applies its target only in operation enabled).
    pub fn torque_allowed(&self) -> bool {
        self.wanted
            && self.latched.is_none()
            && self.reset == ResetEdge::Idle
            && matches!(self.state, State::SwitchedOn | State::OperationEnabled)
    }

    /// This cycle's controlword.
    pub fn controlword(&mut self) -> u16 {
        match self.reset {
            ResetEdge::Low => {
                self.reset = ResetEdge::High;
                return controlword::DISABLE_VOLTAGE;
            }
            ResetEdge::High => {
                self.reset = ResetEdge::Sent;
                return controlword::FAULT_RESET;
            }
            ResetEdge::Idle | ResetEdge::Sent => {}
        }
        match (self.wanted, self.latched) {
            (true, None) => towards_enabled(self.state),
            _ => controlword::DISABLE_VOLTAGE,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Statuswords as CiA 402 defines them and drive manuals (maxon's EPOS4 firmware
    /// specification, for one) list them: bit 4 (voltage enabled), 9 (remote) and the others
    /// above bit 6 do not change the state.
    #[test]
    fn statuswords_read_as_the_standards_states() {
        let cases = [
            (0x0000, State::NotReadyToSwitchOn),
            (0x0250, State::SwitchOnDisabled),
            (0x0221, State::ReadyToSwitchOn),
            (0x0231, State::ReadyToSwitchOn),
            (0x0233, State::SwitchedOn),
            (0x0237, State::OperationEnabled),
            (0x1637, State::OperationEnabled),
            (0x0217, State::QuickStopActive),
            (0x021F, State::FaultReactionActive),
            (0x0218, State::Fault),
            (0x0208, State::Fault),
        ];
        for (statusword, state) in cases {
            assert_eq!(State::of(statusword), state, "{statusword:#06x}");
        }
        assert_eq!(State::of(0x0001), State::Unknown(0x0001));
    }

    /// Figure 8's transitions 2, 3 and 4 (shutdown, switch on, enable operation) from switch on
    /// disabled, one per cycle as the drive answers.
    #[test]
    fn enabling_walks_the_state_machine_only_when_asked() {
        let mut axis = Axis::default();
        axis.observe(0x0250);
        assert_eq!(axis.controlword(), controlword::DISABLE_VOLTAGE, "not asked: stays disabled");
        axis.enable().unwrap();
        let mut sent = Vec::new();
        for statusword in [0x0250, 0x0231, 0x0233, 0x0237, 0x0237] {
            axis.observe(statusword);
            sent.push(axis.controlword());
        }
        assert_eq!(sent, [0x06, 0x07, 0x0F, 0x0F, 0x0F]);
        assert!(axis.torque_allowed());
        axis.disable();
        assert_eq!(axis.controlword(), controlword::DISABLE_VOLTAGE);
        assert!(!axis.torque_allowed());
    }

    #[test]
    fn a_fault_latches_disables_and_never_re_enables_by_itself() {
        let mut axis = Axis::default();
        axis.enable().unwrap();
        axis.observe(0x0237);
        axis.observe(0x0218);
        assert_eq!(axis.latched(), Some(AxisFault::Drive { statusword: 0x0218 }));
        assert!(!axis.torque_allowed());
        // The drive recovers by itself: the latch holds, and so does the disable.
        axis.observe(0x0250);
        assert_eq!(axis.controlword(), controlword::DISABLE_VOLTAGE);
        assert!(matches!(axis.enable(), Err(Latched(_))));
        // A master fault latches alike.
        let mut other = Axis::default();
        other.enable().unwrap();
        other.observe(0x0237);
        other.latch(AxisFault::Master);
        assert_eq!(other.controlword(), controlword::DISABLE_VOLTAGE);
        assert!(!other.torque_allowed());
    }

    /// A drive enabled by the walk that then stops by itself (its quick-stop input: quick stop
    /// active, then switch on disabled; safe torque off: switch on disabled or not ready) latches
    /// in the cycle it reports it, gets disable voltage from then on, and is enabled again only
    /// by the operator's reset and enable.
    #[test]
    fn a_drive_that_stops_by_itself_latches_and_is_not_walked_back() {
        for stopped in [0x0217, 0x0250, 0x0200, 0x0233, 0x0221] {
            let mut axis = Axis::default();
            axis.enable().unwrap();
            for statusword in [0x0250, 0x0231, 0x0233, 0x1237] {
                axis.observe(statusword);
                axis.controlword();
            }
            assert!(axis.torque_allowed());
            axis.observe(stopped);
            assert_eq!(axis.latched(), Some(AxisFault::Stopped { statusword: stopped }), "{stopped:#06x}");
            assert!(!axis.torque_allowed());
            let after: Vec<u16> = [0x0250, 0x0250, 0x0250]
                .iter()
                .map(|&s| {
                    axis.observe(s);
                    axis.controlword()
                })
                .collect();
            assert_eq!(after, [0, 0, 0], "no walk back after {stopped:#06x}");
            assert!(axis.enable().is_err());
            axis.reset();
            assert_eq!(axis.controlword(), 0, "a drive not in fault gets no reset edge");
            axis.enable().unwrap();
            axis.observe(0x0250);
            assert_eq!(axis.controlword(), controlword::SHUTDOWN, "walked again after the operator's reset and enable");
        }
    }

    /// During the walk a state repeats while the drive's statusword lags the controlword; a step
    /// back, or a state the walk never leads to, is the drive stopping by itself.
    #[test]
    fn during_the_walk_a_step_back_latches_and_a_repeat_does_not() {
        let mut axis = Axis::default();
        axis.enable().unwrap();
        for statusword in [0x0250, 0x0250, 0x0231, 0x0231, 0x0233] {
            axis.observe(statusword);
            assert_eq!(axis.latched(), None, "{statusword:#06x}");
        }
        axis.observe(0x0250);
        assert_eq!(axis.latched(), Some(AxisFault::Stopped { statusword: 0x0250 }));
        let mut quick = Axis::default();
        quick.enable().unwrap();
        quick.observe(0x0217);
        assert_eq!(quick.latched(), Some(AxisFault::Stopped { statusword: 0x0217 }), "held in quick stop");
        // The operator's disable is the master's command: the drive may go back, and nothing latches.
        let mut off = Axis::default();
        off.enable().unwrap();
        off.observe(0x0237);
        off.disable();
        off.observe(0x0250);
        assert_eq!(off.latched(), None);
        off.enable().unwrap();
        off.observe(0x0250);
        assert_eq!((off.latched(), off.controlword()), (None, controlword::SHUTDOWN));
    }

    /// A fault reset is one rising edge of bit 7 on the operator's reset, and the axis stays
    /// disabled until the operator enables it again.
    #[test]
    fn the_operators_reset_sends_one_edge_and_leaves_the_axis_disabled() {
        let mut axis = Axis::default();
        axis.enable().unwrap();
        axis.observe(0x0218);
        assert_eq!(axis.controlword(), 0x0000);
        axis.reset();
        let sent = [axis.controlword(), axis.controlword(), axis.controlword()];
        assert_eq!(sent, [0x0000, 0x0080, 0x0000]);
        axis.observe(0x0250);
        assert_eq!(axis.latched(), None);
        assert_eq!(axis.controlword(), controlword::DISABLE_VOLTAGE, "not re-enabled by the reset");
        axis.enable().unwrap();
        axis.observe(0x0250);
        assert_eq!(axis.controlword(), controlword::SHUTDOWN);
    }

    /// An edge whose frame the bus refused goes again, once; a delivered one does not.
    #[test]
    fn a_refused_reset_edge_is_sent_again() {
        let mut axis = Axis::default();
        axis.observe(0x0218);
        axis.reset();
        assert_eq!([axis.controlword(), axis.controlword()], [0x0000, 0x0080]);
        axis.edge_lost();
        assert_eq!([axis.controlword(), axis.controlword(), axis.controlword()], [0x0000, 0x0080, 0x0000]);
        axis.observe(0x0250);
        axis.edge_lost();
        assert_eq!([axis.controlword(), axis.controlword()], [0x0000; 2], "the drive left its fault: no edge after it");
    }

    #[test]
    fn torque_is_permille_of_the_rated_saturated_and_never_nan() {
        // A rated torque of 0.5 N·m (500 mN·m in 0x6076), limited to 150 % (0x6072 = 1500).
        let scale = RatedScale::new(500, 1500).unwrap();
        assert_eq!(scale.permille(0.25), Ok(500));
        assert_eq!(scale.permille(-0.1), Ok(-200));
        assert_eq!(scale.permille(10.0), Ok(1500));
        assert_eq!(scale.permille(-10.0), Ok(-1500));
        assert!(scale.permille(f64::NAN).is_err());
        assert!(scale.permille(f64::INFINITY).is_err());
        assert!((scale.value(-200) + 0.1).abs() < 1e-12);
        assert_eq!(RatedScale::new(0, 1000), None);
    }

    #[test]
    fn process_data_frames_carry_the_mapped_objects_little_endian() {
        let node = NodeId::try_from(4).unwrap();
        let rpdo = rpdo1(node, controlword::ENABLE_OPERATION, -300);
        assert_eq!((rpdo.id, rpdo.len), (0x204, 4));
        assert_eq!(&rpdo.data[..4], &[0x0F, 0x00, 0xD4, 0xFE]);
        let tpdo = Tpdo1 { node, statusword: 0x1637, position: -70000, torque_permille: 123 };
        let frame = tpdo.frame();
        assert_eq!((frame.id, frame.len), (0x184, 8));
        assert_eq!(frame.data, [0x37, 0x16, 0x90, 0xEE, 0xFE, 0xFF, 123, 0]);
        assert_eq!(Tpdo1::parse(&frame), Some(tpdo));
        assert_eq!(Tpdo1::parse(&CanFrame { len: 6, ..frame }), None);
    }
}
