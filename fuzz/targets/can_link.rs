//! Arbitrary CAN frames on the bus (any identifier, length and data) through the host's CAN link:
//! never a panic, and only complete telemetry sets are reported.

use arash_daemon::link::can::{CanBus, CanFrame, CanLink, InProcessBus};
use arash_daemon::link::{MotorLink, Telemetry};

pub fn check(data: &[u8]) {
    let Some((&first, rest)) = data.split_first() else { return };
    let joints = 1 + usize::from(first) % 8;
    let (host, mut drive) = InProcessBus::pair(4096);
    let mut link = CanLink::new(host, joints);
    let mut telemetry = Telemetry::new(joints);
    for chunk in rest.chunks(13) {
        if chunk.len() < 13 {
            break;
        }
        let frame = CanFrame {
            id: u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]),
            len: chunk[4],
            data: chunk[5..13].try_into().unwrap(),
        };
        if drive.send(&frame).is_err() {
            break;
        }
        if chunk[4] & 0x80 != 0 {
            // Poll between frames now and then, as the control cycle does once per period.
            if link.poll(&mut telemetry).unwrap() {
                assert_eq!(telemetry.joints, joints);
            }
        }
    }
    let _ = link.poll(&mut telemetry);
}
