//! Bytes off the serial cable, in arbitrary read sizes, through the host's link: never a panic,
//! every decoded frame re-encodes to a frame that decodes to the same message, and the counters
//! account for what arrived.

use std::io::{Read, Write};

use arash_daemon::link::frame::{decode, encode, Deframer, MAX_WIRE};
use arash_daemon::link::serial::SerialLink;
use arash_daemon::link::{MotorLink, Telemetry};

/// A port that hands out the input in reads of the sizes the input itself chooses.
struct Wire<'a> {
    bytes: &'a [u8],
    sizes: &'a [u8],
    turn: usize,
}

impl Read for Wire<'_> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        if self.bytes.is_empty() {
            return Err(std::io::ErrorKind::WouldBlock.into());
        }
        let size = self.sizes.get(self.turn % self.sizes.len().max(1)).map_or(64, |&s| usize::from(s) + 1);
        self.turn += 1;
        let n = size.min(out.len()).min(self.bytes.len());
        out[..n].copy_from_slice(&self.bytes[..n]);
        self.bytes = &self.bytes[n..];
        Ok(n)
    }
}

impl Write for Wire<'_> {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        Ok(bytes.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

pub fn check(data: &[u8]) {
    let (sizes, bytes) = data.split_at(data.len().min(4));
    let joints = 1 + usize::from(sizes.first().copied().unwrap_or(2)) % 8;
    let mut link = SerialLink::new(Wire { bytes, sizes, turn: 0 }, joints);
    let mut telemetry = Telemetry::new(joints);
    let _ = link.poll(&mut telemetry);
    let stats = link.stats();
    assert!(stats.frames_received <= bytes.len() as u64);

    let mut deframer = Deframer::default();
    deframer.push(bytes, |frame| {
        if let Ok(message) = frame {
            let mut wire = [0u8; MAX_WIRE];
            let n = encode(&message, &mut wire);
            assert_eq!(wire[n - 1], 0, "a frame ends with its delimiter");
            assert_eq!(decode(&wire[..n - 1]), Ok(message), "re-encoding changed the message");
        }
    });
}
