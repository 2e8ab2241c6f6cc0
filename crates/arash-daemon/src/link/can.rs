//! The motor link over classic CAN (8-byte frames; CAN's own CRC protects each frame).
//!
//! | direction | identifier | data |
//! |---|---|---|
//! | host → drive | `0x100 + type` (types as in the serial protocol, except currents) | `seq: u16` |
//! | host → drive | `0x110 + joint` current setpoint | `amps: f32`, `seq: u16`, 2 bytes zero |
//! | drive → host | `0x180 + joint` telemetry | `counts: i32`, `current: i16` (mA), `seq: u8`, `status \| faults << 2` |
//!
//! A cycle's telemetry is the set of one frame per joint with the same `seq`; an incomplete set
//! is not telemetry (the cycle counts as missing), exactly like a lost serial frame.
//! [`SocketCan`] is the Linux transport; [`InProcessBus`] connects the host to a drive model in
//! the same process (the test machines have no CAN support in their kernels).

use super::frame::{kind, Command, Telemetry, MAX_JOINTS};
use super::{LinkStats, MotorLink, SequenceCheck};

pub const COMMAND_BASE: u32 = 0x100;
pub const CURRENT_BASE: u32 = 0x110;
pub const TELEMETRY_BASE: u32 = 0x180;

/// A classic CAN frame (11-bit identifier).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CanFrame {
    pub id: u32,
    pub len: u8,
    pub data: [u8; 8],
}

/// Moves CAN frames; never blocks.
pub trait CanBus: Send {
    fn send(&mut self, frame: &CanFrame) -> std::io::Result<()>;
    /// The next received frame, if any. Frames the transport cannot give as an 11-bit data
    /// frame (extended, remote, error frames) are counted in [`BusHealth`], not returned.
    fn receive(&mut self) -> std::io::Result<Option<CanFrame>>;
    /// What the controller or adapter reported since the bus was opened; a bus that cannot tell
    /// reports nothing.
    fn health(&self) -> BusHealth {
        BusHealth::default()
    }
    /// Housekeeping at most once per control cycle: an slcan adapter is asked for its status
    /// flags here, at a bounded rate.
    fn service(&mut self) -> std::io::Result<()> {
        Ok(())
    }
    /// Wait until a frame may have arrived, or `timeout` (the lockstep pace); a bus that cannot
    /// tell sleeps it.
    fn wait(&self, timeout: std::time::Duration) {
        std::thread::sleep(timeout);
    }
}

/// What a CAN transport has reported about the bus and about itself, counted since it was
/// opened. The first three latch the CANopen master's `fieldbus` fault when they grow
/// ([`BusHealth::faults`]); the others are shown, not acted on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BusHealth {
    /// Frames or commands the adapter refused (slcan's BEL; a full SocketCAN queue is an error
    /// of the send itself).
    pub refused: u64,
    /// Reports of the bus in error: an slcan status with error passive or bus error, a
    /// SocketCAN error frame (bus-off, controller, no acknowledgement).
    pub bus_errors: u64,
    /// Frames lost on the way: an slcan status with a full FIFO or a data overrun, or the host's
    /// own receive queue full.
    pub overruns: u64,
    /// slcan statuses with only the error-warning flag: the bus works, its error counters are high.
    pub warnings: u64,
    /// Lines from the adapter that are not its protocol.
    pub malformed: u64,
    /// Frames no CANopen node sends the master: extended and remote frames.
    pub foreign: u64,
    /// The adapter's last status flags (slcan `F`), when it reports them.
    pub status_flags: Option<u8>,
    /// Whether the adapter answers the status request at all (slcan `F`): when it does not,
    /// error passive and bus-off show only as refused frames.
    pub reports_status: bool,
}

impl BusHealth {
    /// The reports that latch a fault: refusals, bus errors and lost frames.
    pub fn faults(&self) -> u64 {
        self.refused + self.bus_errors + self.overruns
    }
}

/// The frames that carry `command` with sequence number `seq`, into `out`; returns how many.
pub fn command_frames(command: &Command, seq: u16, out: &mut [CanFrame; MAX_JOINTS]) -> usize {
    let s = seq.to_le_bytes();
    let simple = |k: u8| CanFrame { id: COMMAND_BASE + u32::from(k), len: 2, data: [s[0], s[1], 0, 0, 0, 0, 0, 0] };
    out[0] = match command {
        Command::Enable => simple(kind::ENABLE),
        Command::Disable => simple(kind::DISABLE),
        Command::ZeroEncoders => simple(kind::ZERO_ENCODERS),
        Command::Heartbeat => simple(kind::HEARTBEAT),
        Command::ClearFault => simple(kind::CLEAR_FAULT),
        Command::Current { joints, amps } => {
            for (j, (f, a)) in out.iter_mut().zip(&amps[..*joints]).enumerate() {
                let b = a.to_le_bytes();
                *f = CanFrame { id: CURRENT_BASE + j as u32, len: 8, data: [b[0], b[1], b[2], b[3], s[0], s[1], 0, 0] };
            }
            return *joints;
        }
    };
    1
}

/// One joint's telemetry frame.
pub fn telemetry_frame(t: &Telemetry, joint: usize) -> CanFrame {
    let c = t.counts[joint].to_le_bytes();
    let ma = (t.amps[joint] * 1000.0).round().clamp(i16::MIN as f32, i16::MAX as f32) as i16;
    let m = ma.to_le_bytes();
    CanFrame {
        id: TELEMETRY_BASE + joint as u32,
        len: 8,
        data: [c[0], c[1], c[2], c[3], m[0], m[1], t.seq as u8, (t.status & 0b11) | (t.faults << 2)],
    }
}

/// The host side over any [`CanBus`].
pub struct CanLink<B> {
    bus: B,
    joints: usize,
    seq: u16,
    frames: [CanFrame; MAX_JOINTS],
    /// The telemetry set being assembled, and which joints it has.
    partial: Telemetry,
    have: u32,
    sequence: SequenceCheck,
    stats: LinkStats,
}

impl<B: CanBus> CanLink<B> {
    pub fn new(bus: B, joints: usize) -> Self {
        assert!(joints <= MAX_JOINTS);
        Self {
            bus,
            joints,
            seq: 0,
            frames: [CanFrame::default(); MAX_JOINTS],
            partial: Telemetry::new(joints),
            have: 0,
            sequence: SequenceCheck::new(8),
            stats: LinkStats::default(),
        }
    }

    /// Fold one telemetry frame into the set being assembled; `true` completes a set.
    fn absorb(&mut self, f: &CanFrame) -> bool {
        let joint = (f.id - TELEMETRY_BASE) as usize;
        if joint >= self.joints || f.len != 8 {
            self.stats.framing_errors += 1;
            return false;
        }
        let seq = f.data[6];
        if self.have != 0 && seq != self.partial.seq as u8 {
            // A new cycle began before the last set was complete: that set is lost (the sequence
            // gap counts it).
            self.have = 0;
        }
        let p = &mut self.partial;
        p.seq = u16::from(seq);
        p.counts[joint] = i32::from_le_bytes([f.data[0], f.data[1], f.data[2], f.data[3]]);
        p.amps[joint] = f32::from(i16::from_le_bytes([f.data[4], f.data[5]])) / 1000.0;
        p.status = f.data[7] & 0b11;
        p.faults = f.data[7] >> 2;
        self.have |= 1 << joint;
        self.have == (1 << self.joints) - 1
    }
}

impl<B: CanBus> MotorLink for CanLink<B> {
    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        let n = command_frames(command, self.seq, &mut self.frames);
        self.seq = self.seq.wrapping_add(1);
        for f in &self.frames[..n] {
            if let Err(e) = self.bus.send(f) {
                self.stats.send_errors += 1;
                return Err(e);
            }
        }
        self.stats.frames_sent += 1;
        Ok(())
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        let mut fresh = false;
        while let Some(f) = self.bus.receive()? {
            if !(TELEMETRY_BASE..TELEMETRY_BASE + MAX_JOINTS as u32).contains(&f.id) {
                self.stats.framing_errors += 1;
                continue;
            }
            if !self.absorb(&f) {
                continue;
            }
            self.have = 0;
            match self.sequence.accept(self.partial.seq) {
                Some(gap) => self.stats.lost += u64::from(gap),
                None => {
                    self.stats.stale += 1;
                    continue;
                }
            }
            self.stats.frames_received += 1;
            *out = self.partial;
            fresh = true;
        }
        Ok(fresh)
    }

    fn stats(&self) -> LinkStats {
        self.stats
    }
}

/// Both ends of an in-process CAN bus: frames the host sends arrive at the drive and back.
/// Bounded and wait-free; a full bus refuses a frame like a controller with a full mailbox.
pub struct InProcessBus {
    tx: rtrb::Producer<CanFrame>,
    rx: rtrb::Consumer<CanFrame>,
}

impl InProcessBus {
    /// A (host, drive) pair holding up to `capacity` frames each way.
    pub fn pair(capacity: usize) -> (Self, Self) {
        let (host_tx, drive_rx) = rtrb::RingBuffer::new(capacity);
        let (drive_tx, host_rx) = rtrb::RingBuffer::new(capacity);
        (Self { tx: host_tx, rx: host_rx }, Self { tx: drive_tx, rx: drive_rx })
    }
}

impl CanBus for InProcessBus {
    fn send(&mut self, frame: &CanFrame) -> std::io::Result<()> {
        self.tx.push(*frame).map_err(|_| std::io::Error::new(std::io::ErrorKind::WouldBlock, "CAN bus full"))
    }

    fn receive(&mut self) -> std::io::Result<Option<CanFrame>> {
        Ok(self.rx.pop().ok())
    }
}

/// A raw SocketCAN socket bound to one interface (Linux).
#[cfg(target_os = "linux")]
pub struct SocketCan {
    fd: std::os::fd::OwnedFd,
    /// Error frames (the kernel sends them only to sockets that ask) and foreign frames.
    health: BusHealth,
}

#[cfg(target_os = "linux")]
impl SocketCan {
    /// Open `interface` (e.g. `can0`), non-blocking. Fails with the interface named when the
    /// kernel has no CAN support or no such interface.
    pub fn open(interface: &str) -> std::io::Result<Self> {
        use std::os::fd::FromRawFd;
        let name = std::ffi::CString::new(interface)
            .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "interface name contains NUL"))?;
        let context = |e: std::io::Error| std::io::Error::new(e.kind(), format!("CAN interface {interface}: {e}"));
        // SAFETY: plain libc calls with checked results; the descriptor is owned right away.
        let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if index == 0 {
            return Err(context(std::io::Error::last_os_error()));
        }
        let raw = unsafe { libc::socket(libc::PF_CAN, libc::SOCK_RAW | libc::SOCK_NONBLOCK, libc::CAN_RAW) };
        if raw < 0 {
            return Err(context(std::io::Error::last_os_error()));
        }
        let fd = unsafe { std::os::fd::OwnedFd::from_raw_fd(raw) };
        let mut addr: libc::sockaddr_can = unsafe { std::mem::zeroed() };
        addr.can_family = libc::AF_CAN as libc::sa_family_t;
        addr.can_ifindex = index as i32;
        let bound = unsafe {
            libc::bind(
                raw,
                &addr as *const libc::sockaddr_can as *const libc::sockaddr,
                std::mem::size_of::<libc::sockaddr_can>() as libc::socklen_t,
            )
        };
        if bound < 0 {
            return Err(context(std::io::Error::last_os_error()));
        }
        // Error frames for bus-off, controller problems and a missing acknowledgement (no other
        // node on the bus): a master of drives must see them.
        let mask: libc::can_err_mask_t = libc::CAN_ERR_BUSOFF | libc::CAN_ERR_CRTL | libc::CAN_ERR_ACK;
        // SAFETY: a valid socket descriptor, and a pointer to the mask with its size, as
        // CAN_RAW_ERR_FILTER takes.
        let set = unsafe {
            libc::setsockopt(
                raw,
                libc::SOL_CAN_RAW,
                libc::CAN_RAW_ERR_FILTER,
                (&mask as *const libc::can_err_mask_t).cast(),
                std::mem::size_of::<libc::can_err_mask_t>() as libc::socklen_t,
            )
        };
        if set < 0 {
            return Err(context(std::io::Error::last_os_error()));
        }
        Ok(Self { fd, health: BusHealth::default() })
    }
}

#[cfg(target_os = "linux")]
impl CanBus for SocketCan {
    fn send(&mut self, frame: &CanFrame) -> std::io::Result<()> {
        use std::os::fd::AsRawFd;
        let mut raw: libc::can_frame = unsafe { std::mem::zeroed() };
        raw.can_id = frame.id;
        raw.can_dlc = frame.len;
        raw.data = frame.data;
        let size = std::mem::size_of::<libc::can_frame>();
        // SAFETY: writes exactly one can_frame from a live stack value.
        let n =
            unsafe { libc::write(self.fd.as_raw_fd(), &raw as *const libc::can_frame as *const libc::c_void, size) };
        if n != size as isize {
            return Err(std::io::Error::last_os_error());
        }
        Ok(())
    }

    fn receive(&mut self) -> std::io::Result<Option<CanFrame>> {
        use std::os::fd::AsRawFd;
        loop {
            let mut raw: libc::can_frame = unsafe { std::mem::zeroed() };
            let size = std::mem::size_of::<libc::can_frame>();
            // SAFETY: reads at most one can_frame into a live stack value.
            let n =
                unsafe { libc::read(self.fd.as_raw_fd(), &mut raw as *mut libc::can_frame as *mut libc::c_void, size) };
            if n < 0 {
                let e = std::io::Error::last_os_error();
                return if e.kind() == std::io::ErrorKind::WouldBlock { Ok(None) } else { Err(e) };
            }
            if raw.can_id & libc::CAN_ERR_FLAG != 0 {
                self.health.bus_errors += 1;
            } else if n as usize != size || raw.can_id & (libc::CAN_EFF_FLAG | libc::CAN_RTR_FLAG) != 0 {
                self.health.foreign += 1;
            } else {
                return Ok(Some(CanFrame { id: raw.can_id & libc::CAN_SFF_MASK, len: raw.can_dlc, data: raw.data }));
            }
        }
    }

    fn health(&self) -> BusHealth {
        self.health
    }

    fn wait(&self, timeout: std::time::Duration) {
        use std::os::fd::AsRawFd;
        super::wait_readable(self.fd.as_raw_fd(), timeout);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn telemetry(seq: u16) -> Telemetry {
        let mut t = Telemetry::new(3);
        t.seq = seq;
        t.status = crate::link::frame::status::ENABLED;
        t.faults = crate::link::frame::drive_fault::ENCODER;
        t.counts[..3].copy_from_slice(&[-70_000, 5, 123_456]);
        t.amps[..3].copy_from_slice(&[0.25, -1.5, 3.0]);
        t
    }

    fn send_set(drive: &mut InProcessBus, t: &Telemetry, joints: &[usize]) {
        for &j in joints {
            drive.send(&telemetry_frame(t, j)).unwrap();
        }
    }

    #[test]
    fn a_complete_set_is_telemetry_and_currents_arrive_as_sent() {
        let (host, mut drive) = InProcessBus::pair(64);
        let mut link = CanLink::new(host, 3);
        let mut amps = [0f32; MAX_JOINTS];
        amps[..3].copy_from_slice(&[0.5, -0.25, 2.0]);
        link.send(&Command::Current { joints: 3, amps }).unwrap();
        for (j, &a) in amps[..3].iter().enumerate() {
            let f = drive.receive().unwrap().unwrap();
            assert_eq!(f.id, CURRENT_BASE + j as u32);
            assert_eq!(f32::from_le_bytes(f.data[..4].try_into().unwrap()), a);
        }
        send_set(&mut drive, &telemetry(9), &[2, 0, 1]);
        let mut out = Telemetry::new(3);
        assert!(link.poll(&mut out).unwrap());
        assert_eq!(out, telemetry(9));
    }

    #[test]
    fn an_incomplete_set_is_a_lost_cycle_and_a_repeat_is_stale() {
        let (host, mut drive) = InProcessBus::pair(64);
        let mut link = CanLink::new(host, 3);
        let mut out = Telemetry::new(3);
        send_set(&mut drive, &telemetry(1), &[0, 1, 2]);
        assert!(link.poll(&mut out).unwrap());
        send_set(&mut drive, &telemetry(2), &[0, 1]);
        assert!(!link.poll(&mut out).unwrap(), "joint 2 never came");
        send_set(&mut drive, &telemetry(3), &[0, 1, 2]);
        assert!(link.poll(&mut out).unwrap());
        assert_eq!(out.seq, 3);
        assert_eq!(link.stats().lost, 1, "the broken set leaves a sequence gap");
        send_set(&mut drive, &telemetry(3), &[0, 1, 2]);
        assert!(!link.poll(&mut out).unwrap());
        assert_eq!(link.stats().stale, 1);
    }

    #[test]
    fn a_missing_interface_is_named() {
        let Err(e) = SocketCan::open("arash-no-such-can") else { panic!("opened a CAN interface that does not exist") };
        assert!(e.to_string().contains("arash-no-such-can"), "{e}");
    }
}
