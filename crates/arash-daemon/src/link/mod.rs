//! The motor link: how the daemon talks to the motor drives (docs/protocol.md).
//!
//! - [`frame`]: the serial protocol's frames (COBS, CRC-16, sequence numbers, time stamps);
//! - [`serial`]: that protocol over a byte stream (a serial port, or a pseudo-terminal);
//! - [`can`]: the same commands and telemetry as classic CAN frames;
//! - [`slcan`]: CAN frames over a serial line in the Lawicel ASCII protocol (USB adapters);
//! - [`canopen`] and [`cia402`]: the CANopen frames and the CiA 402 axis supervision a master of
//!   standard drives needs (sans-I/O);
//! - [`drive_setup`]: a CiA 402 drive's start-up over SDO (sans-I/O, and a blocking runner);
//! - [`master`]: a CANopen master of CiA 402 drives on any CAN transport (SocketCAN, slcan).
//!
//! The three links (serial, CAN, CANopen) implement [`MotorLink`]; the control cycle sees only
//! the trait. None blocks or allocates in `send` or `poll`.

pub mod can;
pub mod canopen;
pub mod cia402;
pub mod drive_setup;
pub mod frame;
pub mod master;
pub mod serial;
pub mod slcan;

pub use frame::{Command, Telemetry, MAX_JOINTS};

/// Counters of what went wrong on the link, logged once a second, shown by `arash ctl status`
/// and written into each log's metadata when it closes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct LinkStats {
    pub frames_sent: u64,
    pub frames_received: u64,
    /// Frames whose CRC did not match.
    pub crc_errors: u64,
    /// Byte runs that were not frames (COBS, length, type or body errors).
    pub framing_errors: u64,
    /// Telemetry frames missing between two received ones (sequence gaps).
    pub lost: u64,
    /// Telemetry frames that arrived out of order or twice, and were dropped.
    pub stale: u64,
    /// Sends that failed (e.g. a full output buffer).
    pub send_errors: u64,
    /// What a CAN transport reported: refused frames, bus errors, lost frames, malformed
    /// lines, foreign frames, the adapter's status flags (CAN links only).
    pub bus: Option<can::BusHealth>,
    /// Why a CANopen master latched its drives off, in words.
    #[serde(serialize_with = "in_words")]
    pub latched: Option<master::MasterFault>,
    /// The joints (a bit each) whose drive's start-up a CANopen master is running again after
    /// the operator's reset; shown as the list of their indices.
    #[serde(serialize_with = "joint_list")]
    pub recovering: u8,
}

fn joint_list<S: serde::Serializer>(joints: &u8, s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq((0..8).filter(|j| joints & (1 << j) != 0))
}

fn in_words<S: serde::Serializer>(fault: &Option<master::MasterFault>, s: S) -> Result<S::Ok, S::Error> {
    match fault {
        Some(f) => s.collect_str(f),
        None => s.serialize_none(),
    }
}

impl LinkStats {
    /// Every kind of error counted so far, the transport's included.
    pub fn errors(&self) -> u64 {
        let bus = self.bus.map_or(0, |b| b.faults() + b.malformed);
        self.crc_errors + self.framing_errors + self.lost + self.stale + self.send_errors + bus
    }
}

/// A transport to the motor drives.
pub trait MotorLink: Send {
    /// Bring the drives up, on the control thread just before its first cycle: what the link
    /// found, a line each for the operator. A link whose drives need no start-up has none.
    fn start(&mut self) -> Result<Vec<String>, Box<dyn std::error::Error + Send + Sync>> {
        Ok(Vec::new())
    }
    /// Queue one command frame. Never blocks: a frame that cannot be written now is counted in
    /// `send_errors` and reported as an error.
    fn send(&mut self, command: &Command) -> std::io::Result<()>;
    /// Take everything that has arrived. Returns `true` when at least one new, valid telemetry
    /// frame came, with the newest written to `out`. A link that supervises its drives itself
    /// (the CANopen master) writes `out.faults` on every call, new telemetry or not.
    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool>;
    fn stats(&self) -> LinkStats;
    /// Time the telemetry by its samples (count × period), not by the host's clock: the lockstep
    /// pace (rt/clock.rs), where a simulated rig's time is its steps. A link whose telemetry
    /// carries the drive's own clock has nothing to change.
    fn clock_by_samples(&mut self) {}
    /// Wait until something has arrived or `timeout` has passed (the lockstep pace, for a
    /// simulated rig: rt/clock.rs). A link that cannot tell sleeps the timeout.
    fn wait(&mut self, timeout: std::time::Duration) {
        std::thread::sleep(timeout);
    }
}

/// Wait until `fd` is readable or `timeout` has passed.
pub fn wait_readable(fd: std::os::fd::RawFd, timeout: std::time::Duration) {
    let mut pfd = libc::pollfd { fd, events: libc::POLLIN, revents: 0 };
    let ts = libc::timespec {
        tv_sec: timeout.as_secs().min(i32::MAX as u64) as libc::time_t,
        tv_nsec: libc::c_long::from(timeout.subsec_nanos() as i32),
    };
    // SAFETY: one pollfd and one timespec on the stack, no signal mask; the result only tells
    // whether to read.
    unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
}

/// Tracks the drive's telemetry sequence numbers (`bits` wide, wrapping): gaps are counted as
/// lost frames, and a frame not newer than the last accepted one (within half the range) is
/// stale.
#[derive(Clone, Copy, Debug)]
pub struct SequenceCheck {
    mask: u16,
    last: Option<u16>,
}

impl Default for SequenceCheck {
    fn default() -> Self {
        Self::new(16)
    }
}

impl SequenceCheck {
    pub fn new(bits: u32) -> Self {
        Self { mask: (((1u32 << bits) - 1) & 0xFFFF) as u16, last: None }
    }

    /// `Some(gap)` (frames lost before this one) if `seq` is new, `None` if stale.
    pub fn accept(&mut self, seq: u16) -> Option<u16> {
        let seq = seq & self.mask;
        let gap = match self.last {
            None => 0,
            Some(last) => {
                let ahead = seq.wrapping_sub(last) & self.mask;
                if ahead == 0 || ahead > self.mask / 2 {
                    return None;
                }
                ahead - 1
            }
        };
        self.last = Some(seq);
        Some(gap)
    }
}

#[cfg(test)]
mod tests {
    use super::SequenceCheck;

    #[test]
    fn sequence_numbers_wrap_count_gaps_and_reject_stale_frames() {
        let mut s = SequenceCheck::default();
        assert_eq!(s.accept(65534), Some(0));
        assert_eq!(s.accept(65535), Some(0));
        assert_eq!(s.accept(2), Some(2), "0 and 1 were lost across the wrap");
        assert_eq!(s.accept(2), None, "duplicate");
        assert_eq!(s.accept(1), None, "reordered");
        assert_eq!(s.accept(3), Some(0));
        let mut s8 = SequenceCheck::new(8);
        assert_eq!(s8.accept(255), Some(0));
        assert_eq!(s8.accept(256 + 1), Some(1), "only the low 8 bits count");
    }
}
