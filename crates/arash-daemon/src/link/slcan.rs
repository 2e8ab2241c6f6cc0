//! CAN over a serial line in the Lawicel ASCII protocol ("slcan"), as CANable-type USB adapters
//! speak it: one line per frame or command, ended by `\r`.
//!
//! | line | meaning |
//! |---|---|
//! | `tIIILDD…\r` | a classic frame: 3 hex digits of 11-bit identifier, the length 0–8, the data in hex |
//! | `TIIIIIIIILDD…\r` | an extended frame (29-bit identifier): CANopen does not use them |
//! | `rIIIL\r`, `RIIIIIIIIL\r` | a remote request |
//! | `\r`, `z\r`, `Z\r` | the adapter accepted the last command or frame |
//! | `\a` (BEL) | the adapter refused the last command or frame |
//! | `Fxx\r` | the adapter's status flags (answer to `F\r`) |
//!
//! The codec is sans-I/O ([`encode`], [`Decoder`]); [`SlcanBus`] puts it on a byte stream. Nothing
//! here allocates after construction.

use std::io::{ErrorKind, Read, Write};
use std::time::{Duration, Instant};

use super::can::{BusHealth, CanBus, CanFrame};

/// The longest line the encoder writes: `t`, 3 digits, the length, 16 data digits, `\r`.
pub const MAX_ENCODED: usize = 22;

/// The longest line the decoder accepts: an extended frame with a 4-digit time stamp.
const MAX_LINE: usize = 1 + 8 + 1 + 16 + 4;

/// The largest classic (11-bit) identifier.
pub const MAX_STANDARD_ID: u32 = 0x7FF;

/// The bit rates an slcan adapter sets with `S0`…`S8` (bit/s).
pub const BIT_RATES: [u32; 9] = [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000];

/// Why a frame cannot be sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    #[error("CAN identifier {0:#x} is not an 11-bit identifier (at most 0x7ff)")]
    Identifier(u32),
    #[error("CAN frame length {0} is more than 8 bytes")]
    Length(u8),
}

/// `frame` as an slcan line into `out`; returns its length.
pub fn encode(frame: &CanFrame, out: &mut [u8; MAX_ENCODED]) -> Result<usize, EncodeError> {
    if frame.id > MAX_STANDARD_ID {
        return Err(EncodeError::Identifier(frame.id));
    }
    if frame.len > 8 {
        return Err(EncodeError::Length(frame.len));
    }
    out[0] = b't';
    for (i, shift) in [8, 4, 0].into_iter().enumerate() {
        out[1 + i] = hex_digit((frame.id >> shift) as u8 & 0xF);
    }
    out[4] = b'0' + frame.len;
    let mut at = 5;
    for byte in &frame.data[..usize::from(frame.len)] {
        out[at] = hex_digit(byte >> 4);
        out[at + 1] = hex_digit(byte & 0xF);
        at += 2;
    }
    out[at] = b'\r';
    Ok(at + 1)
}

/// The setup lines for an adapter at `bit_rate`: close (in case it was open), set the rate, open.
pub fn setup_lines(bit_rate: u32) -> Result<[&'static [u8]; 3], UnsupportedBitRate> {
    const RATES: [&[u8]; 9] = [b"S0\r", b"S1\r", b"S2\r", b"S3\r", b"S4\r", b"S5\r", b"S6\r", b"S7\r", b"S8\r"];
    let code = BIT_RATES.iter().position(|&r| r == bit_rate).ok_or(UnsupportedBitRate(bit_rate))?;
    Ok([b"C\r", RATES[code], b"O\r"])
}

/// A bit rate the slcan protocol has no code for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("bit rate {0} bit/s is not one an slcan adapter sets (10k, 20k, 50k, 100k, 125k, 250k, 500k, 800k or 1M)")]
pub struct UnsupportedBitRate(pub u32);

/// What one line from the adapter says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    Frame(CanFrame),
    /// An extended or remote frame: no CANopen node sends one to the master.
    Foreign,
    /// The adapter accepted the last command or frame.
    Accepted,
    /// The adapter refused the last command or frame (`\a`).
    Refused,
    /// The status flags (`Fxx`): bit 2 error warning, bit 3 data overrun, bit 5 error passive,
    /// bit 7 bus error.
    Status(u8),
    /// A line that is none of the above, or too long.
    Malformed,
}

/// Splits the adapter's bytes into lines and reads each.
#[derive(Debug, Clone)]
pub struct Decoder {
    line: [u8; MAX_LINE],
    len: usize,
    /// The current line overflowed: it is malformed, whatever follows until its `\r`.
    overflow: bool,
}

impl Default for Decoder {
    fn default() -> Self {
        Self { line: [0; MAX_LINE], len: 0, overflow: false }
    }
}

impl Decoder {
    /// Take one byte; `Some` when it ends a line (or is a BEL, which stands alone).
    pub fn push(&mut self, byte: u8) -> Option<Event> {
        match byte {
            0x07 => {
                self.len = 0;
                self.overflow = false;
                Some(Event::Refused)
            }
            b'\r' => {
                let event = match self.overflow {
                    true => Event::Malformed,
                    false => parse_line(&self.line[..self.len]),
                };
                self.len = 0;
                self.overflow = false;
                Some(event)
            }
            // Some adapters end their lines with `\r\n`.
            b'\n' if self.len == 0 => None,
            _ => {
                if self.len == MAX_LINE {
                    self.overflow = true;
                } else {
                    self.line[self.len] = byte;
                    self.len += 1;
                }
                None
            }
        }
    }
}

fn parse_line(line: &[u8]) -> Event {
    match line.first() {
        None | Some(b'z') | Some(b'Z') if line.len() <= 1 => Event::Accepted,
        Some(b't') => parse_standard(&line[1..]).map_or(Event::Malformed, Event::Frame),
        Some(b'T') | Some(b'r') | Some(b'R') => Event::Foreign,
        Some(b'F') if line.len() == 3 => match (hex_value(line[1]), hex_value(line[2])) {
            (Some(h), Some(l)) => Event::Status(h << 4 | l),
            _ => Event::Malformed,
        },
        _ => Event::Malformed,
    }
}

/// `IIILDD…`, optionally followed by a 4-digit time stamp, which is ignored.
fn parse_standard(body: &[u8]) -> Option<CanFrame> {
    if body.len() < 4 {
        return None;
    }
    let mut id = 0u32;
    for &c in &body[..3] {
        id = id << 4 | u32::from(hex_value(c)?);
    }
    let len = body[3].checked_sub(b'0').filter(|l| *l <= 8)?;
    let data_digits = 2 * usize::from(len);
    let rest = body.len() - 4;
    if id > MAX_STANDARD_ID || (rest != data_digits && rest != data_digits + 4) {
        return None;
    }
    let mut frame = CanFrame { id, len, data: [0; 8] };
    for (i, pair) in body[4..4 + data_digits].chunks_exact(2).enumerate() {
        frame.data[i] = hex_value(pair[0])? << 4 | hex_value(pair[1])?;
    }
    body[4 + data_digits..].iter().all(|c| hex_value(*c).is_some()).then_some(frame)
}

fn hex_digit(nibble: u8) -> u8 {
    b"0123456789ABCDEF"[usize::from(nibble & 0xF)]
}

fn hex_value(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'A'..=b'F' => Some(c - b'A' + 10),
        b'a'..=b'f' => Some(c - b'a' + 10),
        _ => None,
    }
}

/// The status flags of an slcan adapter (the answer to `F`, Lawicel's CAN232 and CANUSB
/// manuals), each with what it means for a master of drives.
pub mod flags {
    /// Frames were lost: the receive or transmit FIFO was full, or the controller overran.
    pub const LOST: u8 = RECEIVE_FIFO_FULL | TRANSMIT_FIFO_FULL | DATA_OVERRUN;
    /// The bus is in error: error passive, or a bus error (bus-off among them).
    pub const BUS_ERROR: u8 = ERROR_PASSIVE | BUS_ERROR_BIT;
    pub const RECEIVE_FIFO_FULL: u8 = 1 << 0;
    pub const TRANSMIT_FIFO_FULL: u8 = 1 << 1;
    pub const ERROR_WARNING: u8 = 1 << 2;
    pub const DATA_OVERRUN: u8 = 1 << 3;
    pub const ERROR_PASSIVE: u8 = 1 << 5;
    pub const ARBITRATION_LOST: u8 = 1 << 6;
    pub const BUS_ERROR_BIT: u8 = 1 << 7;

    /// The names of the flags set, for messages.
    pub fn names(flags: u8) -> impl Iterator<Item = &'static str> {
        const NAMES: [&str; 8] = [
            "receive FIFO full",
            "transmit FIFO full",
            "error warning",
            "data overrun",
            "bit 4",
            "error passive",
            "arbitration lost",
            "bus error",
        ];
        NAMES.into_iter().enumerate().filter(move |(i, _)| flags & (1 << i) != 0).map(|(_, n)| n)
    }
}

/// How often the adapter is asked for its status flags (`F`): the bound on how late an
/// error-passive or bus-off adapter is seen. Two bytes each way, a few per cent of a USB serial
/// line's time at 1 kHz.
pub const STATUS_POLL: Duration = Duration::from_millis(10);

/// How long the adapter has at start-up to answer the first `F`. One that does not (some
/// CANable firmwares answer BEL, others nothing) is not asked again.
const STATUS_PROBE: Duration = Duration::from_millis(50);

/// A [`CanBus`] on an slcan adapter behind a byte stream (a serial port set non-blocking, or a
/// pseudo-terminal).
pub struct SlcanBus<P> {
    port: P,
    decoder: Decoder,
    received: std::collections::VecDeque<CanFrame>,
    /// Lines (or their ends) the port would not take yet: a non-blocking port may write part of
    /// a line, and the rest must follow before any other line, or the adapter reads garbage.
    unsent: std::collections::VecDeque<u8>,
    health: BusHealth,
    /// When the adapter was last asked for its status (`None`: it does not answer).
    status_asked: Option<Instant>,
    /// The port's descriptor, to wait on (the lockstep pace); `None`: the wait sleeps.
    readable: Option<std::os::fd::RawFd>,
}

/// Frames held between two `receive` calls: a 1 kHz cycle reads a few per joint.
const QUEUE: usize = 256;

/// Bytes held for a port that is slow to take them: 4 kB, some 180 frames, or 18 cycles of a
/// master of eight drives. A frame that does not fit is refused whole.
const UNSENT: usize = 4096;

impl<P: Read + Write + Send> SlcanBus<P> {
    /// Set the adapter to `bit_rate`, open the bus, and find out whether the adapter reports its
    /// status flags (one `F`, answered within 50 ms or never asked again).
    pub fn open(port: P, bit_rate: u32) -> std::io::Result<Self> {
        Self::open_probing(port, bit_rate, STATUS_PROBE)
    }

    /// [`SlcanBus::open`], waiting `probe` for the status answer (what the port holds is read at
    /// least once): a test's or a fuzzer's byte source answers at once or never.
    pub fn open_probing(mut port: P, bit_rate: u32, probe: Duration) -> std::io::Result<Self> {
        let lines = setup_lines(bit_rate).map_err(|e| std::io::Error::new(ErrorKind::InvalidInput, e))?;
        for line in lines {
            port.write_all(line)?;
        }
        port.flush()?;
        let mut bus = Self {
            port,
            decoder: Decoder::default(),
            received: std::collections::VecDeque::with_capacity(QUEUE),
            unsent: std::collections::VecDeque::with_capacity(UNSENT),
            health: BusHealth::default(),
            status_asked: None,
            readable: None,
        };
        bus.probe_status(probe)?;
        Ok(bus)
    }

    pub fn health(&self) -> BusHealth {
        self.health
    }

    /// Ask for the status once and wait for its answer. What else arrives meanwhile is kept
    /// (frames) or dropped (the setup's acknowledgements; a refused `C` on an adapter that was
    /// closed is the protocol's answer, not an error).
    fn probe_status(&mut self, probe: Duration) -> std::io::Result<()> {
        self.port.write_all(b"F\r")?;
        self.port.flush()?;
        let deadline = Instant::now() + probe;
        loop {
            self.fill()?;
            if self.health.reports_status || Instant::now() >= deadline {
                break;
            }
            std::thread::sleep(Duration::from_micros(500));
        }
        self.health.refused = 0;
        if self.health.reports_status {
            self.status_asked = Some(Instant::now());
        }
        Ok(())
    }

    /// Write what the port takes now of the lines held back, in order.
    fn flush_unsent(&mut self) -> std::io::Result<()> {
        while !self.unsent.is_empty() {
            let (head, _) = self.unsent.as_slices();
            match self.port.write(head) {
                Ok(0) => return Ok(()),
                Ok(n) => drop(self.unsent.drain(..n)),
                Err(e) if e.kind() == ErrorKind::WouldBlock => return Ok(()),
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// Queue one line for the adapter, whole or not at all.
    fn write_line(&mut self, line: &[u8]) -> std::io::Result<()> {
        self.flush_unsent()?;
        if self.unsent.len() + line.len() > UNSENT {
            return Err(std::io::Error::new(ErrorKind::WouldBlock, "the slcan adapter takes no more lines"));
        }
        self.unsent.extend(line);
        self.flush_unsent()
    }

    /// Read what the port holds now and decode it.
    fn fill(&mut self) -> std::io::Result<()> {
        let mut buffer = [0u8; 512];
        loop {
            let n = match self.port.read(&mut buffer) {
                Ok(0) => return Ok(()),
                Ok(n) => n,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => return Ok(()),
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            for &byte in &buffer[..n] {
                if let Some(event) = self.decoder.push(byte) {
                    self.take(event);
                }
            }
            if n < buffer.len() {
                return Ok(());
            }
        }
    }

    fn take(&mut self, event: Event) {
        let h = &mut self.health;
        match event {
            Event::Frame(frame) if self.received.len() < QUEUE => self.received.push_back(frame),
            Event::Frame(_) => h.overruns += 1,
            Event::Refused => h.refused += 1,
            Event::Malformed => h.malformed += 1,
            Event::Foreign => h.foreign += 1,
            Event::Status(f) => {
                h.reports_status = true;
                h.status_flags = Some(f);
                h.bus_errors += u64::from(f & flags::BUS_ERROR != 0);
                h.overruns += u64::from(f & flags::LOST != 0);
                h.warnings += u64::from(f & flags::ERROR_WARNING != 0 && f & (flags::BUS_ERROR | flags::LOST) == 0);
            }
            Event::Accepted => {}
        }
    }
}

impl<P: Read + Write + Send + std::os::fd::AsRawFd> SlcanBus<P> {
    /// [`SlcanBus::open`] on a port it can wait on until something arrives.
    pub fn on_port(port: P, bit_rate: u32) -> std::io::Result<Self> {
        let readable = Some(port.as_raw_fd());
        Ok(Self { readable, ..Self::open(port, bit_rate)? })
    }
}

impl<P: Read + Write + Send> CanBus for SlcanBus<P> {
    fn send(&mut self, frame: &CanFrame) -> std::io::Result<()> {
        let mut line = [0u8; MAX_ENCODED];
        let n = encode(frame, &mut line).map_err(|e| std::io::Error::new(ErrorKind::InvalidInput, e))?;
        self.write_line(&line[..n])
    }

    fn receive(&mut self) -> std::io::Result<Option<CanFrame>> {
        if self.received.is_empty() {
            self.fill()?;
        }
        Ok(self.received.pop_front())
    }

    fn health(&self) -> BusHealth {
        self.health
    }

    fn wait(&self, timeout: Duration) {
        match (self.received.is_empty(), self.readable) {
            (false, _) => {}
            (true, Some(fd)) => super::wait_readable(fd, timeout),
            (true, None) => std::thread::sleep(timeout),
        }
    }

    /// Ask for the status flags every [`STATUS_POLL`], if the adapter answers `F` at all.
    fn service(&mut self) -> std::io::Result<()> {
        match self.status_asked {
            Some(at) if at.elapsed() >= STATUS_POLL => {
                self.status_asked = Some(Instant::now());
                self.write_line(b"F\r")
            }
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_all(bytes: &[u8]) -> Vec<Event> {
        let mut decoder = Decoder::default();
        bytes.iter().filter_map(|&b| decoder.push(b)).collect()
    }

    /// As the Lawicel protocol writes them: identifier 0x123 with the 3 bytes 11 22 33 is
    /// `t1233112233\r` (upper-case hex; the decoder takes either case).
    #[test]
    fn frames_encode_as_the_protocol_writes_them() {
        let mut out = [0u8; MAX_ENCODED];
        let frame = CanFrame { id: 0x123, len: 3, data: [0x11, 0x22, 0x33, 0, 0, 0, 0, 0] };
        let n = encode(&frame, &mut out).unwrap();
        assert_eq!(&out[..n], b"t1233112233\r");
        let sync = CanFrame { id: 0x080, len: 0, data: [0; 8] };
        let n = encode(&sync, &mut out).unwrap();
        assert_eq!(&out[..n], b"t0800\r");
        let full = CanFrame { id: 0x7FF, len: 8, data: [0xDE, 0xAD, 0xBE, 0xEF, 0x01, 0x23, 0x45, 0x67] };
        let n = encode(&full, &mut out).unwrap();
        assert_eq!(&out[..n], b"t7FF8DEADBEEF01234567\r");
        assert_eq!(n, MAX_ENCODED);
        assert_eq!(encode(&CanFrame { id: 0x800, ..sync }, &mut out), Err(EncodeError::Identifier(0x800)));
        assert_eq!(encode(&CanFrame { len: 9, ..sync }, &mut out), Err(EncodeError::Length(9)));
    }

    #[test]
    fn lines_decode_to_frames_acknowledgements_refusals_and_status() {
        let events = decode_all(b"t701105\rtXYZ0\rz\r\x07t58184B01100000000000\rF24\r\r");
        let heartbeat = CanFrame { id: 0x701, len: 1, data: [0x05, 0, 0, 0, 0, 0, 0, 0] };
        let sdo = CanFrame { id: 0x581, len: 8, data: [0x4B, 0x01, 0x10, 0, 0, 0, 0, 0] };
        let expected = [
            Event::Frame(heartbeat),
            Event::Malformed,
            Event::Accepted,
            Event::Refused,
            Event::Frame(sdo),
            Event::Status(0x24),
            Event::Accepted,
        ];
        assert_eq!(events, expected);
    }

    #[test]
    fn lower_case_digits_time_stamps_and_crlf_are_read() {
        let events = decode_all(b"t1812abcd1234\r\nT12345678100\r");
        assert_eq!(events[0], Event::Frame(CanFrame { id: 0x181, len: 2, data: [0xAB, 0xCD, 0, 0, 0, 0, 0, 0] }));
        assert_eq!(events[1], Event::Foreign);
    }

    #[test]
    fn a_wrong_length_or_an_overlong_line_is_malformed_and_decoding_goes_on() {
        let mut bytes = b"t1232AA\rt12300\r".to_vec();
        bytes.extend(std::iter::repeat_n(b'1', 100));
        bytes.extend(b"\rt0800\r");
        let events = decode_all(&bytes);
        let sync = CanFrame { id: 0x080, len: 0, data: [0; 8] };
        assert_eq!(events, [Event::Malformed, Event::Malformed, Event::Malformed, Event::Frame(sync)]);
    }

    #[test]
    fn every_frame_survives_a_round_trip() {
        let mut out = [0u8; MAX_ENCODED];
        for id in [0u32, 1, 0x80, 0x181, 0x5FF, 0x7FF] {
            for len in 0..=8u8 {
                let mut data = [0u8; 8];
                for (i, d) in data.iter_mut().enumerate().take(usize::from(len)) {
                    *d = (id as u8).wrapping_mul(31).wrapping_add(17 * i as u8);
                }
                let frame = CanFrame { id, len, data };
                let n = encode(&frame, &mut out).unwrap();
                assert_eq!(decode_all(&out[..n]), [Event::Frame(frame)]);
            }
        }
    }

    #[test]
    fn the_setup_sets_the_rate_by_its_code_and_refuses_others() {
        let lines = setup_lines(1_000_000).unwrap();
        assert_eq!(&lines[1], b"S8\r");
        assert_eq!(&setup_lines(125_000).unwrap()[1], b"S4\r");
        assert_eq!(setup_lines(333_000), Err(UnsupportedBitRate(333_000)));
    }

    /// A byte stream that hands out what it holds and then says it would block.
    struct Pipe {
        input: std::io::Cursor<Vec<u8>>,
        output: Vec<u8>,
    }

    impl Read for Pipe {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            match self.input.read(buf)? {
                0 => Err(ErrorKind::WouldBlock.into()),
                n => Ok(n),
            }
        }
    }

    impl Write for Pipe {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.output.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// A port that takes at most `room` bytes per call, and nothing while `room` is zero.
    struct Slow {
        room: usize,
        output: Vec<u8>,
    }

    impl Read for Slow {
        fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
            Err(ErrorKind::WouldBlock.into())
        }
    }

    impl Write for Slow {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.room == 0 {
                return Err(ErrorKind::WouldBlock.into());
            }
            let n = buf.len().min(self.room);
            self.output.extend_from_slice(&buf[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// A port that takes part of a line leaves the adapter a whole line later, never a line cut
    /// by another; when nothing more fits, a frame is refused whole.
    #[test]
    fn a_slow_port_gets_whole_lines_in_order_and_a_full_one_refuses_whole_frames() {
        let mut bus = SlcanBus::open(Slow { room: 64, output: Vec::new() }, 1_000_000).unwrap();
        bus.port.output.clear();
        bus.port.room = 5;
        let frame = |id| CanFrame { id, len: 2, data: [0xAB, 0xCD, 0, 0, 0, 0, 0, 0] };
        bus.send(&frame(0x201)).unwrap();
        bus.send(&frame(0x202)).unwrap();
        bus.port.room = 0;
        let mut refused = 0;
        for _ in 0..UNSENT {
            refused += usize::from(bus.send(&frame(0x203)).is_err());
        }
        assert!(refused > 0 && bus.unsent.len() <= UNSENT);
        bus.port.room = usize::MAX;
        bus.flush_unsent().unwrap();
        let text = String::from_utf8(bus.port.output.clone()).unwrap();
        let lines: Vec<&str> = text.split_terminator('\r').collect();
        assert_eq!(&lines[..2], ["t2012ABCD", "t2022ABCD"]);
        assert!(lines[2..].iter().all(|l| *l == "t2032ABCD"), "{lines:?}");
        assert_eq!(lines.len(), 2 + UNSENT - refused, "every accepted frame, whole");
    }

    /// An adapter that does not answer `F` (some CANable firmwares): the setup's answers and a
    /// BEL during the probe are not errors, frames are kept, and it is not asked again.
    #[test]
    fn the_bus_opens_the_adapter_sends_lines_and_counts_what_is_not_a_frame() {
        let input = b"\r\r\rt70117F\r\x07t701105\rZ\r".to_vec();
        let pipe = Pipe { input: std::io::Cursor::new(input), output: Vec::new() };
        let mut bus = SlcanBus::open(pipe, 500_000).unwrap();
        assert_eq!(bus.port.output, b"C\rS6\rO\rF\r");
        assert!(!bus.health().reports_status);
        assert_eq!(bus.health().refused, 0, "the probe's BEL is the adapter's 'no status', not a refused frame");
        bus.send(&CanFrame { id: 0x080, len: 0, data: [0; 8] }).unwrap();
        assert_eq!(&bus.port.output[9..], b"t0800\r");
        let first = bus.receive().unwrap().unwrap();
        assert_eq!((first.id, first.len, first.data[0]), (0x701, 1, 0x7F));
        let second = bus.receive().unwrap().unwrap();
        assert_eq!(second.data[0], 0x05);
        assert_eq!(bus.receive().unwrap(), None);
        std::thread::sleep(STATUS_POLL);
        bus.service().unwrap();
        assert_eq!(&bus.port.output[9..], b"t0800\r", "not asked again");
        bus.port.input = std::io::Cursor::new(b"\x07t1234\rT123456780\rr1230\r".to_vec());
        assert_eq!(bus.receive().unwrap(), None);
        let h = bus.health();
        assert_eq!((h.refused, h.malformed, h.foreign, h.faults()), (1, 1, 2, 1), "{h:?}");
    }

    /// An adapter that answers `F` is asked every [`STATUS_POLL`], no sooner; error passive and
    /// bus error count as bus errors, a full FIFO or an overrun as lost frames, error warning
    /// alone only as a warning.
    #[test]
    fn an_adapter_that_reports_its_status_is_asked_at_a_bounded_rate_and_its_flags_are_read() {
        let pipe = Pipe { input: std::io::Cursor::new(b"\r\r\rF00\r".to_vec()), output: Vec::new() };
        let mut bus = SlcanBus::open(pipe, 1_000_000).unwrap();
        assert!(bus.health().reports_status);
        assert_eq!((bus.health().status_flags, bus.health().faults()), (Some(0), 0));
        bus.port.output.clear();
        bus.service().unwrap();
        assert!(bus.port.output.is_empty(), "asked again before {STATUS_POLL:?}");
        std::thread::sleep(STATUS_POLL);
        bus.service().unwrap();
        bus.service().unwrap();
        assert_eq!(bus.port.output, b"F\r", "once per period");
        for (line, bus_errors, overruns, warnings) in [
            (&b"F20\r"[..], 1, 0, 0),
            (b"F80\r", 2, 0, 0),
            (b"F08\r", 2, 1, 0),
            (b"F01\r", 2, 2, 0),
            (b"F04\r", 2, 2, 1),
            (b"F24\r", 3, 2, 1),
        ] {
            bus.port.input = std::io::Cursor::new(line.to_vec());
            assert_eq!(bus.receive().unwrap(), None);
            let h = bus.health();
            assert_eq!((h.bus_errors, h.overruns, h.warnings), (bus_errors, overruns, warnings), "{line:?}");
        }
        assert_eq!(bus.health().status_flags, Some(0x24));
        assert_eq!(flags::names(0xA8).collect::<Vec<_>>(), ["data overrun", "error passive", "bus error"]);
    }
}
