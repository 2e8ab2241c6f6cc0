//! The framed protocol over a byte stream: a serial port, a pseudo-terminal, or any
//! `Read + Write` (tests use in-memory pipes).

use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use super::frame::{self, Command, Deframer, FrameError, Message, Telemetry, MAX_WIRE};
use super::{LinkStats, MotorLink, SequenceCheck};

/// One end of a framed byte stream; the host and the mock motor each hold one. The stream must
/// be non-blocking: a read with nothing to read returns `WouldBlock` or `TimedOut`.
pub struct Endpoint<P> {
    port: P,
    deframer: Deframer,
    read_buffer: [u8; 1024],
    wire: [u8; MAX_WIRE],
    seq: u16,
    epoch: std::time::Instant,
}

impl<P: Read + Write> Endpoint<P> {
    pub fn new(port: P) -> Self {
        Self {
            port,
            deframer: Deframer::default(),
            read_buffer: [0; 1024],
            wire: [0; MAX_WIRE],
            seq: 0,
            epoch: std::time::Instant::now(),
        }
    }

    /// Microseconds since this endpoint was created (wrapping), the frames' time stamp.
    pub fn clock_us(&self) -> u32 {
        self.epoch.elapsed().as_micros() as u32
    }

    /// The sequence number the next frame will carry.
    pub fn next_seq(&self) -> u16 {
        self.seq
    }

    /// Encode and write a command with the next sequence number and the current time stamp.
    pub fn send_command(&mut self, command: &Command) -> std::io::Result<()> {
        let message = Message::Command { seq: self.seq, time_us: self.clock_us(), command: *command };
        self.seq = self.seq.wrapping_add(1);
        self.write_message(&message)
    }

    /// Encode and write a message as given (its sequence number and time stamp included).
    pub fn write_message(&mut self, message: &Message) -> std::io::Result<()> {
        let n = frame::encode(message, &mut self.wire);
        self.write_bytes(n)
    }

    /// Write the frame in the wire buffer; a partial write is an error (the frame is lost).
    fn write_bytes(&mut self, n: usize) -> std::io::Result<()> {
        let written = self.port.write(&self.wire[..n])?;
        if written != n {
            return Err(std::io::Error::new(ErrorKind::WouldBlock, "output buffer full: frame cut short"));
        }
        Ok(())
    }

    /// Write raw bytes (the mock motor uses this to corrupt frames).
    pub fn write_raw(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.port.write_all(bytes)
    }

    /// Read all available bytes, calling `on_frame` for every frame they complete.
    pub fn receive(&mut self, mut on_frame: impl FnMut(Result<Message, FrameError>)) -> std::io::Result<()> {
        loop {
            match self.port.read(&mut self.read_buffer) {
                Ok(0) => return Ok(()),
                Ok(n) => self.deframer.push(&self.read_buffer[..n], &mut on_frame),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted) => {
                    return Ok(())
                }
                Err(e) => return Err(e),
            }
        }
    }

    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }
}

/// The host's side of the serial protocol.
pub struct SerialLink<P> {
    endpoint: Endpoint<P>,
    sequence: SequenceCheck,
    stats: LinkStats,
    joints: usize,
    /// The port's descriptor, to wait on (the lockstep pace); `None`: the wait sleeps.
    readable: Option<std::os::fd::RawFd>,
}

impl<P: Read + Write> SerialLink<P> {
    pub fn new(port: P, joints: usize) -> Self {
        let endpoint = Endpoint::new(port);
        Self { endpoint, sequence: SequenceCheck::default(), stats: LinkStats::default(), joints, readable: None }
    }
}

impl<P: Read + Write + std::os::fd::AsRawFd> SerialLink<P> {
    /// The link on a port it can wait on until something arrives.
    pub fn on_port(port: P, joints: usize) -> Self {
        let readable = Some(port.as_raw_fd());
        Self { readable, ..Self::new(port, joints) }
    }
}

impl<P: Read + Write + Send> MotorLink for SerialLink<P> {
    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        match self.endpoint.send_command(command) {
            Ok(()) => {
                self.stats.frames_sent += 1;
                Ok(())
            }
            Err(e) => {
                self.stats.send_errors += 1;
                Err(e)
            }
        }
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        let (stats, sequence, joints) = (&mut self.stats, &mut self.sequence, self.joints);
        let mut fresh = false;
        self.endpoint.receive(|result| match result {
            Ok(Message::Telemetry(t)) if t.joints == joints => match sequence.accept(t.seq) {
                Some(gap) => {
                    stats.frames_received += 1;
                    stats.lost += u64::from(gap);
                    *out = t;
                    fresh = true;
                }
                None => stats.stale += 1,
            },
            Err(FrameError::Crc) => stats.crc_errors += 1,
            // Wrong joint count, a command echoed back, or bytes that are no frame.
            Ok(_) | Err(_) => stats.framing_errors += 1,
        })?;
        Ok(fresh)
    }

    fn stats(&self) -> LinkStats {
        self.stats
    }

    fn wait(&mut self, timeout: Duration) {
        match self.readable {
            Some(fd) => super::wait_readable(fd, timeout),
            None => std::thread::sleep(timeout),
        }
    }
}

/// Open a serial device (or the slave side of a pseudo-terminal) for the protocol: raw, 8N1,
/// exclusive, and non-blocking so that neither reads nor writes can stall the control cycle.
pub fn open_port(path: &str, baud: u32) -> std::io::Result<serialport::TTYPort> {
    let port = serialport::new(path, baud)
        .timeout(Duration::ZERO)
        .open_native()
        .map_err(|e| std::io::Error::other(format!("opening serial port {path}: {e}")))?;
    set_nonblocking(&port)?;
    Ok(port)
}

/// Set `O_NONBLOCK`: serialport polls before reading but its writes may otherwise block when
/// the far end stops reading.
pub fn set_nonblocking(fd: &impl std::os::fd::AsRawFd) -> std::io::Result<()> {
    let fd = fd.as_raw_fd();
    // SAFETY: fcntl on a descriptor we own, with integer arguments only.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) } < 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}
