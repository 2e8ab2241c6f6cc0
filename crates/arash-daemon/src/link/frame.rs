//! Frames of the serial motor protocol (docs/protocol.md): a payload of type, sequence number,
//! sender time stamp and body, closed by a CRC-16/CCITT-FALSE, COBS-encoded and terminated by a
//! zero byte. Encoding and decoding work in caller buffers and never allocate.

use crc::{Crc, CRC_16_IBM_3740};

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, not reflected), called IBM-3740 in the catalogue.
pub const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// Most joints a frame carries.
pub const MAX_JOINTS: usize = 8;
/// Type, sequence number and time stamp.
pub const HEADER_LEN: usize = 7;
pub const CRC_LEN: usize = 2;
/// Longest payload: a telemetry frame for [`MAX_JOINTS`] joints, with its CRC.
pub const MAX_PAYLOAD: usize = HEADER_LEN + 4 + 8 * MAX_JOINTS + CRC_LEN;
/// Longest frame on the wire: COBS adds one byte per 254 and the terminating zero.
pub const MAX_WIRE: usize = MAX_PAYLOAD + MAX_PAYLOAD / 254 + 2;

/// Message types: host → motor below 0x80, motor → host from 0x80.
pub mod kind {
    pub const ENABLE: u8 = 0x01;
    pub const DISABLE: u8 = 0x02;
    pub const CURRENT: u8 = 0x03;
    pub const ZERO_ENCODERS: u8 = 0x04;
    pub const HEARTBEAT: u8 = 0x05;
    pub const CLEAR_FAULT: u8 = 0x06;
    pub const TELEMETRY: u8 = 0x81;
}

/// What the host asks of the motor drive; one frame per control cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    Enable,
    Disable,
    /// Motor current setpoints (A), one per joint.
    Current {
        joints: usize,
        amps: [f32; MAX_JOINTS],
    },
    ZeroEncoders,
    Heartbeat,
    ClearFault,
}

/// Drive status bits (telemetry `status`).
pub mod status {
    /// The power stage is on and follows current setpoints.
    pub const ENABLED: u8 = 1 << 0;
    /// The brake holds the joints (power stage off).
    pub const BRAKE: u8 = 1 << 1;
}

/// Drive fault bits (telemetry `faults`); any set bit latches in the drive until CLEAR_FAULT.
pub mod drive_fault {
    pub const OVERCURRENT: u8 = 1 << 0;
    pub const ENCODER: u8 = 1 << 1;
    pub const OVERTEMPERATURE: u8 = 1 << 2;
    /// No valid host frame within the drive's own watchdog time.
    pub const HOST_TIMEOUT: u8 = 1 << 3;
    pub const UNDERVOLTAGE: u8 = 1 << 4;
    /// A CiA 402 drive in fault, or an emergency of no class above (link/master.rs).
    pub const DRIVE: u8 = 1 << 5;
    /// The CANopen bus: a lost heartbeat, a drive that left operational, bus errors.
    pub const FIELDBUS: u8 = 1 << 6;
    /// A CiA 402 drive that left operation enabled by itself, without a fault (link/master.rs).
    pub const STOPPED: u8 = 1 << 7;

    /// Names of the bits set in `faults`, for status and reports.
    pub fn names(faults: u8) -> Vec<&'static str> {
        const NAMES: [&str; 8] = [
            "overcurrent",
            "encoder",
            "overtemperature",
            "host timeout",
            "undervoltage",
            "drive",
            "fieldbus",
            "stopped by itself",
        ];
        NAMES.iter().enumerate().filter(|(i, _)| faults & (1 << i) != 0).map(|(_, n)| *n).collect()
    }
}

/// One telemetry frame from the drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Telemetry {
    /// Sequence number of the frame itself.
    pub seq: u16,
    /// Drive clock (µs, wrapping).
    pub device_time_us: u32,
    /// Sequence number of the last valid host frame the drive received.
    pub ack_seq: u16,
    pub status: u8,
    pub faults: u8,
    pub joints: usize,
    /// Encoder counts (motor side), one per joint.
    pub counts: [i32; MAX_JOINTS],
    /// Measured motor current (A), one per joint.
    pub amps: [f32; MAX_JOINTS],
}

impl Telemetry {
    pub fn new(joints: usize) -> Self {
        Self {
            seq: 0,
            device_time_us: 0,
            ack_seq: 0,
            status: 0,
            faults: 0,
            joints,
            counts: [0; MAX_JOINTS],
            amps: [0.0; MAX_JOINTS],
        }
    }
}

/// A decoded frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Message {
    Command { seq: u16, time_us: u32, command: Command },
    Telemetry(Telemetry),
}

/// Why bytes between two zero delimiters are not a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    #[error("COBS decoding failed")]
    Cobs,
    #[error("frame of {0} bytes is too short or too long")]
    Length(usize),
    #[error("CRC mismatch")]
    Crc,
    #[error("unknown message type 0x{0:02x}")]
    UnknownType(u8),
    #[error("body of {len} bytes does not fit message type 0x{kind:02x}")]
    Body { kind: u8, len: usize },
}

/// Encode `message` into `wire` (COBS, with the terminating zero); returns the length used.
pub fn encode(message: &Message, wire: &mut [u8; MAX_WIRE]) -> usize {
    let mut payload = [0u8; MAX_PAYLOAD];
    let (kind, seq, time) = match message {
        Message::Command { seq, time_us, command } => (command_kind(command), *seq, *time_us),
        Message::Telemetry(t) => (kind::TELEMETRY, t.seq, t.device_time_us),
    };
    payload[0] = kind;
    payload[1..3].copy_from_slice(&seq.to_le_bytes());
    payload[3..7].copy_from_slice(&time.to_le_bytes());
    let mut len = HEADER_LEN;
    let mut put = |bytes: &[u8]| {
        payload[len..len + bytes.len()].copy_from_slice(bytes);
        len += bytes.len();
    };
    match message {
        Message::Command { command: Command::Current { joints, amps }, .. } => {
            for a in &amps[..*joints] {
                put(&a.to_le_bytes());
            }
        }
        Message::Command { .. } => {}
        Message::Telemetry(t) => {
            put(&t.ack_seq.to_le_bytes());
            put(&[t.status, t.faults]);
            for k in 0..t.joints {
                put(&t.counts[k].to_le_bytes());
                put(&t.amps[k].to_le_bytes());
            }
        }
    }
    let crc = CRC16.checksum(&payload[..len]);
    payload[len..len + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
    len += CRC_LEN;
    let n = cobs::encode(&payload[..len], &mut wire[..]);
    wire[n] = 0;
    n + 1
}

fn command_kind(command: &Command) -> u8 {
    match command {
        Command::Enable => kind::ENABLE,
        Command::Disable => kind::DISABLE,
        Command::Current { .. } => kind::CURRENT,
        Command::ZeroEncoders => kind::ZERO_ENCODERS,
        Command::Heartbeat => kind::HEARTBEAT,
        Command::ClearFault => kind::CLEAR_FAULT,
    }
}

/// Decode the bytes of one frame between delimiters (without the zero).
pub fn decode(encoded: &[u8]) -> Result<Message, FrameError> {
    if encoded.is_empty() || encoded.len() > MAX_WIRE {
        return Err(FrameError::Length(encoded.len()));
    }
    let mut payload = [0u8; MAX_PAYLOAD + 2];
    let report = cobs::decode(encoded, &mut payload).map_err(|_| FrameError::Cobs)?;
    let len = report.frame_size();
    if !(HEADER_LEN + CRC_LEN..=MAX_PAYLOAD).contains(&len) {
        return Err(FrameError::Length(len));
    }
    let (data, crc) = payload[..len].split_at(len - CRC_LEN);
    if CRC16.checksum(data) != u16::from_le_bytes([crc[0], crc[1]]) {
        return Err(FrameError::Crc);
    }
    let kind = data[0];
    let seq = u16::from_le_bytes([data[1], data[2]]);
    let time_us = u32::from_le_bytes([data[3], data[4], data[5], data[6]]);
    let body = &data[HEADER_LEN..];
    let body_error = FrameError::Body { kind, len: body.len() };
    let empty =
        |command| if body.is_empty() { Ok(Message::Command { seq, time_us, command }) } else { Err(body_error) };
    match kind {
        kind::ENABLE => empty(Command::Enable),
        kind::DISABLE => empty(Command::Disable),
        kind::ZERO_ENCODERS => empty(Command::ZeroEncoders),
        kind::HEARTBEAT => empty(Command::Heartbeat),
        kind::CLEAR_FAULT => empty(Command::ClearFault),
        kind::CURRENT => {
            if body.is_empty() || body.len() % 4 != 0 || body.len() / 4 > MAX_JOINTS {
                return Err(body_error);
            }
            let mut amps = [0f32; MAX_JOINTS];
            for (a, b) in amps.iter_mut().zip(body.chunks_exact(4)) {
                *a = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
            Ok(Message::Command { seq, time_us, command: Command::Current { joints: body.len() / 4, amps } })
        }
        kind::TELEMETRY => {
            if body.len() < 4 + 8 || (body.len() - 4) % 8 != 0 {
                return Err(body_error);
            }
            let mut t = Telemetry::new((body.len() - 4) / 8);
            t.seq = seq;
            t.device_time_us = time_us;
            t.ack_seq = u16::from_le_bytes([body[0], body[1]]);
            t.status = body[2];
            t.faults = body[3];
            for (k, b) in body[4..].chunks_exact(8).enumerate() {
                t.counts[k] = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                t.amps[k] = f32::from_le_bytes([b[4], b[5], b[6], b[7]]);
            }
            Ok(Message::Telemetry(t))
        }
        other => Err(FrameError::UnknownType(other)),
    }
}

/// Splits a byte stream at zero delimiters. Bytes beyond the longest frame are discarded up to
/// the next delimiter and reported once as a framing error.
pub struct Deframer {
    buffer: [u8; MAX_WIRE],
    len: usize,
    overflow: bool,
}

impl Default for Deframer {
    fn default() -> Self {
        Self { buffer: [0; MAX_WIRE], len: 0, overflow: false }
    }
}

impl Deframer {
    /// Feed bytes; `on_frame` receives each complete frame's decoding (empty frames, i.e. repeated
    /// delimiters, are skipped). Returns the number of bytes consumed (always all).
    pub fn push(&mut self, bytes: &[u8], mut on_frame: impl FnMut(Result<Message, FrameError>)) {
        for &b in bytes {
            if b == 0 {
                if self.overflow {
                    on_frame(Err(FrameError::Length(MAX_WIRE + 1)));
                } else if self.len > 0 {
                    on_frame(decode(&self.buffer[..self.len]));
                }
                self.len = 0;
                self.overflow = false;
            } else if self.len < MAX_WIRE {
                self.buffer[self.len] = b;
                self.len += 1;
            } else {
                self.overflow = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn telemetry() -> Telemetry {
        let mut t = Telemetry::new(3);
        t.seq = 65535;
        t.device_time_us = 4_000_000_123;
        t.ack_seq = 7;
        t.status = status::ENABLED;
        t.faults = drive_fault::ENCODER;
        t.counts[..3].copy_from_slice(&[-5, 0, i32::MAX]);
        t.amps[..3].copy_from_slice(&[0.25, -1.5, 3.0]);
        t
    }

    #[test]
    fn every_message_survives_a_round_trip() {
        let mut amps = [0f32; MAX_JOINTS];
        amps[..3].copy_from_slice(&[1.0, -2.0, 0.0]);
        let messages = [
            Message::Telemetry(telemetry()),
            Message::Command { seq: 1, time_us: 2, command: Command::Current { joints: 3, amps } },
            Message::Command { seq: 0, time_us: 0, command: Command::Enable },
            Message::Command { seq: 3, time_us: 9, command: Command::Disable },
            Message::Command { seq: 3, time_us: 9, command: Command::ZeroEncoders },
            Message::Command { seq: 3, time_us: 9, command: Command::Heartbeat },
            Message::Command { seq: 3, time_us: 9, command: Command::ClearFault },
        ];
        for m in messages {
            let mut wire = [0u8; MAX_WIRE];
            let n = encode(&m, &mut wire);
            assert_eq!(wire[n - 1], 0);
            assert!(!wire[..n - 1].contains(&0), "COBS leaves no zero inside a frame");
            assert_eq!(decode(&wire[..n - 1]), Ok(m));
        }
    }

    #[test]
    fn the_crc_is_ccitt_false() {
        // The catalogue check value of CRC-16/CCITT-FALSE.
        assert_eq!(CRC16.checksum(b"123456789"), 0x29B1);
    }

    #[test]
    fn a_flipped_bit_fails_the_crc() {
        let mut wire = [0u8; MAX_WIRE];
        let n = encode(&Message::Telemetry(telemetry()), &mut wire);
        let mut payload = [0u8; MAX_PAYLOAD + 2];
        let len = cobs::decode(&wire[..n - 1], &mut payload).unwrap().frame_size();
        for bit in 0..(len - CRC_LEN) * 8 {
            let mut p = payload;
            p[bit / 8] ^= 1 << (bit % 8);
            let mut w = [0u8; MAX_WIRE];
            let m = cobs::encode(&p[..len], &mut w);
            assert_eq!(decode(&w[..m]), Err(FrameError::Crc), "bit {bit}");
        }
    }

    #[test]
    fn the_deframer_finds_frames_split_across_reads_and_after_noise() {
        let mut wire = [0u8; MAX_WIRE];
        let n = encode(&Message::Telemetry(telemetry()), &mut wire);
        let mut stream = vec![0x11, 0x22, 0];
        stream.extend_from_slice(&wire[..n]);
        stream.extend_from_slice(&wire[..n]);
        let mut deframer = Deframer::default();
        let mut results = Vec::new();
        for piece in stream.chunks(5) {
            deframer.push(piece, |r| results.push(r));
        }
        assert_eq!(results.len(), 3);
        assert!(results[0].is_err());
        assert_eq!(results[1], Ok(Message::Telemetry(telemetry())));
        assert_eq!(results[2], results[1]);
    }

    #[test]
    fn an_overlong_run_is_one_framing_error() {
        let mut deframer = Deframer::default();
        let mut results = Vec::new();
        deframer.push(&[1u8; 3 * MAX_WIRE], |r| results.push(r));
        deframer.push(&[0], |r| results.push(r));
        assert_eq!(results, vec![Err(FrameError::Length(MAX_WIRE + 1))]);
    }
}
