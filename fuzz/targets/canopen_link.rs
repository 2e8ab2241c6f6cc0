//! Arbitrary bytes from an slcan adapter (any lines, any garbage, in reads of arbitrary sizes)
//! through the slcan decoder and the CANopen master's frame parsing (TPDO1, EMCY, heartbeat):
//! never a panic, telemetry only of the configured joint count, and only known fault bits.

use std::io::{Read, Write};

use arash_daemon::link::canopen::NodeId;
use arash_daemon::link::drive_setup::DriveInfo;
use arash_daemon::link::frame::drive_fault;
use arash_daemon::link::master::{CanopenConfig, CanopenLink};
use arash_daemon::link::slcan::SlcanBus;
use arash_daemon::link::{MotorLink, Telemetry};

/// The adapter's side of the line: hands out the fuzzer's bytes in chunks, swallows what the
/// master writes.
struct Adapter {
    input: Vec<u8>,
    at: usize,
    chunk: usize,
}

impl Read for Adapter {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.at == self.input.len() {
            return Err(std::io::ErrorKind::WouldBlock.into());
        }
        let n = buf.len().min(self.chunk).min(self.input.len() - self.at);
        buf[..n].copy_from_slice(&self.input[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

impl Write for Adapter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

const KNOWN: u8 = drive_fault::OVERCURRENT
    | drive_fault::ENCODER
    | drive_fault::OVERTEMPERATURE
    | drive_fault::HOST_TIMEOUT
    | drive_fault::UNDERVOLTAGE
    | drive_fault::DRIVE
    | drive_fault::FIELDBUS
    | drive_fault::STOPPED;

pub fn check(data: &[u8]) {
    let Some((&first, rest)) = data.split_first() else { return };
    let joints = 1 + usize::from(first & 0x07);
    let chunk = 1 + usize::from(first >> 3);
    let config = CanopenConfig {
        nodes: (1..=joints as u8).map(|n| NodeId::try_from(n).unwrap()).collect(),
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
    let adapter = Adapter { input: rest.to_vec(), at: 0, chunk };
    let Ok(bus) = SlcanBus::open_probing(adapter, config.bit_rate, std::time::Duration::ZERO) else { return };
    let mut link = CanopenLink::new(bus, &config, &drives);
    let mut telemetry = Telemetry::new(joints);
    for _ in 0..rest.len() / chunk + 1 {
        if link.poll(&mut telemetry).unwrap() {
            assert_eq!(telemetry.joints, joints);
            assert_eq!(telemetry.faults & !KNOWN, 0);
        }
    }
}
