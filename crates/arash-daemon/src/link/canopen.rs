//! CANopen (CiA 301) as a master needs it for CiA 402 drives: the frames of NMT, SYNC,
//! heartbeat, emergency (EMCY) and expedited SDO transfers, and the PDO mapping a cyclic
//! synchronous torque drive is configured with. Sans-I/O: every function takes or gives
//! [`CanFrame`]s, so that the protocol is tested without a bus.
//!
//! | COB-ID | object |
//! |---|---|
//! | `0x000` | NMT command (master → all nodes) |
//! | `0x080` | SYNC |
//! | `0x080 + node` | EMCY |
//! | `0x180 + node` | TPDO1 (drive → master) |
//! | `0x200 + node` | RPDO1 (master → drive) |
//! | `0x580 + node` | SDO reply (drive → master) |
//! | `0x600 + node` | SDO request (master → drive) |
//! | `0x700 + node` | heartbeat |

use super::can::CanFrame;

pub const NMT: u32 = 0x000;
pub const SYNC: u32 = 0x080;
pub const EMCY_BASE: u32 = 0x080;
pub const TPDO1_BASE: u32 = 0x180;
pub const RPDO1_BASE: u32 = 0x200;
pub const SDO_REPLY_BASE: u32 = 0x580;
pub const SDO_REQUEST_BASE: u32 = 0x600;
pub const HEARTBEAT_BASE: u32 = 0x700;

/// A CANopen node ID, 1–127.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub struct NodeId(u8);

/// A node ID outside 1–127.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("CANopen node ID {0} is outside 1–127")]
pub struct BadNodeId(pub u8);

impl TryFrom<u8> for NodeId {
    type Error = BadNodeId;
    fn try_from(id: u8) -> Result<Self, BadNodeId> {
        match id {
            1..=127 => Ok(Self(id)),
            _ => Err(BadNodeId(id)),
        }
    }
}

impl From<NodeId> for u8 {
    fn from(node: NodeId) -> u8 {
        node.0
    }
}

impl NodeId {
    pub fn get(self) -> u8 {
        self.0
    }

    /// The node a frame of the object at `base` (`0x080`, `0x180`, `0x580`, `0x700`, …) came
    /// from, if it is one.
    pub fn of(frame: &CanFrame, base: u32) -> Option<Self> {
        let offset = frame.id.checked_sub(base)?;
        u8::try_from(offset).ok().and_then(|id| Self::try_from(id).ok())
    }
}

impl std::fmt::Display for NodeId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "node {}", self.0)
    }
}

fn frame(id: u32, bytes: &[u8]) -> CanFrame {
    let mut data = [0u8; 8];
    data[..bytes.len()].copy_from_slice(bytes);
    CanFrame { id, len: bytes.len() as u8, data }
}

/// NMT commands (CiA 301, 7.2.8.3.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum NmtCommand {
    Start = 0x01,
    Stop = 0x02,
    EnterPreOperational = 0x80,
    ResetNode = 0x81,
    ResetCommunication = 0x82,
}

/// An NMT command to `node`, or to every node.
pub fn nmt(command: NmtCommand, node: Option<NodeId>) -> CanFrame {
    frame(NMT, &[command as u8, node.map_or(0, NodeId::get)])
}

/// The SYNC object, without a counter.
pub fn sync() -> CanFrame {
    frame(SYNC, &[])
}

/// A node's NMT state as its heartbeat reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NmtState {
    BootUp,
    Stopped,
    Operational,
    PreOperational,
}

impl std::fmt::Display for NmtState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::BootUp => "boot-up",
            Self::Stopped => "stopped",
            Self::Operational => "operational",
            Self::PreOperational => "pre-operational",
        })
    }
}

/// The node and state of a heartbeat (or boot-up) frame; `None` for any other frame.
pub fn heartbeat(frame: &CanFrame) -> Option<(NodeId, NmtState)> {
    let node = NodeId::of(frame, HEARTBEAT_BASE)?;
    if frame.len != 1 {
        return None;
    }
    let state = match frame.data[0] & 0x7F {
        0x00 => NmtState::BootUp,
        0x04 => NmtState::Stopped,
        0x05 => NmtState::Operational,
        0x7F => NmtState::PreOperational,
        _ => return None,
    };
    Some((node, state))
}

/// An emergency message (CiA 301, 7.2.7.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Emergency {
    pub node: NodeId,
    /// The error code; 0x0000 is "error reset or no error".
    pub code: u16,
    /// The error register, object 0x1001.
    pub register: u8,
    pub manufacturer: [u8; 5],
}

impl Emergency {
    /// An EMCY frame (8 bytes at `0x080 + node`); `None` for any other frame, SYNC included.
    pub fn parse(frame: &CanFrame) -> Option<Self> {
        let node = NodeId::of(frame, EMCY_BASE)?;
        if frame.len != 8 {
            return None;
        }
        let d = frame.data;
        Some(Self {
            node,
            code: u16::from_le_bytes([d[0], d[1]]),
            register: d[2],
            manufacturer: [d[3], d[4], d[5], d[6], d[7]],
        })
    }

    /// Whether this reports an error (and not that errors were reset).
    pub fn is_error(&self) -> bool {
        self.code != 0
    }

    /// The error code's class, from its high byte (CiA 301, table 21).
    pub fn class(&self) -> ErrorClass {
        ErrorClass::of(self.code)
    }
}

/// The classes of emergency error codes, by the code's high byte (CiA 301, table 21; 0x73,
/// sensor, from CiA 402).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorClass {
    NoError,
    Generic,
    Current,
    Voltage,
    Temperature,
    DeviceHardware,
    DeviceSoftware,
    AdditionalModules,
    Sensor,
    Monitoring,
    Communication,
    Protocol,
    External,
    AdditionalFunctions,
    DeviceSpecific,
    Unknown,
}

impl ErrorClass {
    pub fn of(code: u16) -> Self {
        // The class is the code's first digit (CiA 301, 7.2.7.1); the second refines it
        // (CiA 402's 0x5113 is a supply of the device hardware, 0x7305 an encoder), and only the
        // sensors and the two kinds of communication fault have their own class here.
        match code >> 8 {
            0x00 => Self::NoError,
            0x10..=0x1F => Self::Generic,
            0x20..=0x2F => Self::Current,
            0x30..=0x3F => Self::Voltage,
            0x40..=0x4F => Self::Temperature,
            0x50..=0x5F => Self::DeviceHardware,
            0x60..=0x6F => Self::DeviceSoftware,
            0x73 => Self::Sensor,
            0x70..=0x7F => Self::AdditionalModules,
            0x81 => Self::Communication,
            0x82 => Self::Protocol,
            0x80..=0x8F => Self::Monitoring,
            0x90..=0x9F => Self::External,
            0xF0..=0xFE => Self::AdditionalFunctions,
            0xFF => Self::DeviceSpecific,
            _ => Self::Unknown,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::NoError => "no error",
            Self::Generic => "generic error",
            Self::Current => "current",
            Self::Voltage => "voltage",
            Self::Temperature => "temperature",
            Self::DeviceHardware => "device hardware",
            Self::DeviceSoftware => "device software",
            Self::AdditionalModules => "additional modules",
            Self::Sensor => "sensor",
            Self::Monitoring => "monitoring (communication)",
            Self::Communication => "communication",
            Self::Protocol => "protocol error",
            Self::External => "external error",
            Self::AdditionalFunctions => "additional functions",
            Self::DeviceSpecific => "device specific",
            Self::Unknown => "unknown class",
        }
    }
}

/// An object dictionary entry: index and sub-index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Object {
    pub index: u16,
    pub sub: u8,
}

impl std::fmt::Display for Object {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#06x}:{}", self.index, self.sub)
    }
}

/// An expedited SDO transfer the master starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SdoRequest {
    /// Read an object (upload).
    Read(Object),
    /// Write `value`'s low `size` bytes (1–4) to an object (download).
    Write { object: Object, value: u32, size: u8 },
}

impl SdoRequest {
    pub fn object(&self) -> Object {
        match *self {
            Self::Read(object) | Self::Write { object, .. } => object,
        }
    }

    /// The request frame to `node`: initiate upload (`0x40`), or expedited download with the
    /// size given (`0x23`, `0x27`, `0x2B`, `0x2F` for 4, 3, 2, 1 bytes).
    pub fn frame(&self, node: NodeId) -> CanFrame {
        let Object { index, sub } = self.object();
        let [i0, i1] = index.to_le_bytes();
        let (command, value) = match *self {
            Self::Read(_) => (0x40, 0),
            Self::Write { value, size, .. } => {
                assert!((1..=4).contains(&size), "an expedited SDO carries 1 to 4 bytes, not {size}");
                (0x23 | ((4 - size) << 2), value)
            }
        };
        let v = value.to_le_bytes();
        frame(SDO_REQUEST_BASE + u32::from(node.get()), &[command, i0, i1, sub, v[0], v[1], v[2], v[3]])
    }
}

/// What a node answered to an [`SdoRequest`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SdoReply {
    Written,
    /// The value read, with its size in bytes when the node gave it.
    Read {
        value: u32,
        size: Option<u8>,
    },
}

/// An SDO transfer that did not complete.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SdoError {
    #[error("{node} aborted the SDO transfer of {object} with code {code:#010x} ({})", abort_meaning(*code))]
    Aborted { node: NodeId, object: Object, code: u32 },
    #[error("{node} answered the SDO transfer of {object} with a segmented transfer, which this master does not do")]
    Segmented { node: NodeId, object: Object },
    #[error("{node} answered the SDO transfer of {object} with command byte {command:#04x}, which is not its answer")]
    Unexpected { node: NodeId, object: Object, command: u8 },
    #[error("{node} did not answer the SDO transfer of {object} within {timeout_ms} ms")]
    Timeout { node: NodeId, object: Object, timeout_ms: u32 },
}

/// `frame`'s answer to `request` sent to `node`: `None` when the frame is not an SDO reply of
/// that node about that object (another transfer's, or another object's).
pub fn sdo_reply(frame: &CanFrame, node: NodeId, request: &SdoRequest) -> Option<Result<SdoReply, SdoError>> {
    if NodeId::of(frame, SDO_REPLY_BASE) != Some(node) || frame.len != 8 {
        return None;
    }
    let d = frame.data;
    let object = Object { index: u16::from_le_bytes([d[1], d[2]]), sub: d[3] };
    if object != request.object() {
        return None;
    }
    let command = d[0];
    let value = u32::from_le_bytes([d[4], d[5], d[6], d[7]]);
    Some(match (request, command >> 5) {
        (_, 4) => Err(SdoError::Aborted { node, object, code: value }),
        (SdoRequest::Write { .. }, 3) => Ok(SdoReply::Written),
        (SdoRequest::Read(_), 2) => match (command & 0b10 != 0, command & 0b01 != 0) {
            (true, true) => {
                let size = 4 - ((command >> 2) & 0b11);
                let value = value & (u32::MAX >> (8 * (4 - u32::from(size))));
                Ok(SdoReply::Read { value, size: Some(size) })
            }
            (true, false) => Ok(SdoReply::Read { value, size: None }),
            (false, _) => Err(SdoError::Segmented { node, object }),
        },
        _ => Err(SdoError::Unexpected { node, object, command }),
    })
}

/// An SDO abort code in words (CiA 301, table 22), for the common ones.
pub fn abort_meaning(code: u32) -> &'static str {
    match code {
        0x0503_0000 => "toggle bit not alternated",
        0x0504_0000 => "SDO protocol timed out",
        0x0504_0001 => "command specifier not valid or unknown",
        0x0601_0000 => "unsupported access to an object",
        0x0601_0001 => "attempt to read a write-only object",
        0x0601_0002 => "attempt to write a read-only object",
        0x0602_0000 => "object does not exist in the object dictionary",
        0x0604_0041 => "object cannot be mapped to the PDO",
        0x0604_0042 => "the number and length of the objects to be mapped would exceed the PDO length",
        0x0604_0043 => "general parameter incompatibility",
        0x0604_0047 => "general internal incompatibility in the device",
        0x0606_0000 => "access failed due to a hardware error",
        0x0607_0010 => "data type does not match, length of service parameter does not match",
        0x0609_0011 => "sub-index does not exist",
        0x0609_0030 => "invalid value for parameter (download only)",
        0x0609_0031 => "value of parameter written too high",
        0x0609_0032 => "value of parameter written too low",
        0x0800_0000 => "general error",
        0x0800_0020 => "data cannot be transferred or stored to the application",
        0x0800_0021 => "data cannot be transferred or stored because of local control",
        0x0800_0022 => "data cannot be transferred or stored because of the present device state",
        _ => "see the drive's manual",
    }
}

/// A PDO mapping entry (objects 0x1600… and 0x1A00…): index, sub-index and length in bits.
pub fn mapping_entry(object: Object, bits: u8) -> u32 {
    u32::from(object.index) << 16 | u32::from(object.sub) << 8 | u32::from(bits)
}

/// A COB-ID entry's "PDO not valid" bit: set while the PDO is remapped.
pub const PDO_INVALID: u32 = 1 << 31;

/// Transmission type "synchronous, every SYNC" (objects 0x1400:2 and 0x1800:2).
pub const SYNCHRONOUS_EVERY_SYNC: u32 = 1;

/// The SDO writes that map `objects` (each with its length in bits) to a PDO with
/// communication parameters at `communication` (0x1400 + n or 0x1800 + n) and mapping at
/// `mapping` (0x1600 + n or 0x1A00 + n), transmitted on every SYNC at `cob_id`: invalidate the
/// PDO, clear its mapping, write the entries, set their count, the transmission type, and
/// validate it again (CiA 301, 7.5.2.36).
pub fn map_pdo(
    communication: u16,
    mapping: u16,
    cob_id: u32,
    objects: &[(Object, u8)],
) -> impl Iterator<Item = SdoRequest> + '_ {
    let write = move |index, sub, value, size| SdoRequest::Write { object: Object { index, sub }, value, size };
    let entries =
        objects.iter().enumerate().map(move |(i, &(o, bits))| write(mapping, i as u8 + 1, mapping_entry(o, bits), 4));
    [write(communication, 1, cob_id | PDO_INVALID, 4), write(mapping, 0, 0, 1)].into_iter().chain(entries).chain([
        write(mapping, 0, objects.len() as u32, 1),
        write(communication, 2, SYNCHRONOUS_EVERY_SYNC, 1),
        write(communication, 1, cob_id, 4),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(id: u8) -> NodeId {
        NodeId::try_from(id).unwrap()
    }

    #[test]
    fn node_ids_are_1_to_127() {
        assert_eq!(NodeId::try_from(0), Err(BadNodeId(0)));
        assert_eq!(NodeId::try_from(128), Err(BadNodeId(128)));
        assert_eq!(node(127).get(), 127);
        let parsed: Result<NodeId, _> = serde_json::from_str("200");
        assert!(parsed.unwrap_err().to_string().contains("outside 1–127"));
    }

    /// CiA 301's frames byte for byte: "start node 5" is `000#0105`, a boot-up `705#00`, a
    /// heartbeat in operational `705#05`, in pre-operational `705#7F`.
    #[test]
    fn nmt_sync_and_heartbeat_frames_are_the_standards() {
        let start = nmt(NmtCommand::Start, Some(node(5)));
        assert_eq!((start.id, start.len, &start.data[..2]), (0x000, 2, &[0x01, 0x05][..]));
        let all = nmt(NmtCommand::ResetCommunication, None);
        assert_eq!(&all.data[..2], &[0x82, 0x00]);
        assert_eq!((sync().id, sync().len), (0x080, 0));
        let beat = |id, state| CanFrame { id, len: 1, data: [state, 0, 0, 0, 0, 0, 0, 0] };
        assert_eq!(heartbeat(&beat(0x705, 0x00)), Some((node(5), NmtState::BootUp)));
        assert_eq!(heartbeat(&beat(0x705, 0x05)), Some((node(5), NmtState::Operational)));
        assert_eq!(heartbeat(&beat(0x77F, 0x7F)), Some((node(127), NmtState::PreOperational)));
        assert_eq!(heartbeat(&beat(0x705, 0x85)), Some((node(5), NmtState::Operational)), "toggle bit");
        assert_eq!(heartbeat(&beat(0x700, 0x05)), None, "node 0");
        assert_eq!(heartbeat(&beat(0x705, 0x42)), None);
    }

    /// An EMCY "over-current" (0x2310) with error register 0x03 (generic, current) from node 2;
    /// SYNC shares the base COB-ID and is not an emergency.
    #[test]
    fn emergencies_are_read_and_sync_is_not_one() {
        let emcy = CanFrame { id: 0x082, len: 8, data: [0x10, 0x23, 0x03, 1, 2, 3, 4, 5] };
        let e = Emergency::parse(&emcy).unwrap();
        assert_eq!((e.node, e.code, e.register, e.manufacturer), (node(2), 0x2310, 0x03, [1, 2, 3, 4, 5]));
        assert!(e.is_error());
        assert_eq!(e.class(), ErrorClass::Current);
        assert_eq!(e.class().name(), "current");
        assert_eq!(Emergency::parse(&sync()), None);
        let reset = CanFrame { data: [0; 8], ..emcy };
        assert!(!Emergency::parse(&reset).unwrap().is_error());
    }

    /// Codes from CiA 402's table (part 2, annex), each in the class of its first digit: a
    /// drive's own codes refine the class and must not fall out of it.
    #[test]
    fn a_drives_refined_codes_keep_their_class() {
        for (code, class) in [
            (0x2214, ErrorClass::Current),           // over-current in the output stage
            (0x3211, ErrorClass::Voltage),           // DC link over-voltage
            (0x4310, ErrorClass::Temperature),       // drive temperature
            (0x5113, ErrorClass::DeviceHardware),    // +5 V supply low
            (0x6320, ErrorClass::DeviceSoftware),    // parameter error
            (0x7121, ErrorClass::AdditionalModules), // motor blocked
            (0x7305, ErrorClass::Sensor),            // incremental sensor 1 fault
            (0x8130, ErrorClass::Communication),     // heartbeat or life guard error
            (0x8611, ErrorClass::Monitoring),        // following error
            (0xA000, ErrorClass::Unknown),
        ] {
            assert_eq!(ErrorClass::of(code), class, "{code:#06x}");
        }
    }

    /// The command bytes of CiA 301's expedited transfers: download of 4 bytes `0x23`, of 2
    /// `0x2B`, of 1 `0x2F`; initiate upload `0x40`. Writing 10 to 0x6060:0 on node 3 is
    /// `603#2F6060000A000000`: the value in the first data byte.
    #[test]
    fn sdo_requests_are_the_standards_bytes() {
        let mode = SdoRequest::Write { object: Object { index: 0x6060, sub: 0 }, value: 10, size: 1 };
        let f = mode.frame(node(3));
        assert_eq!((f.id, f.len), (0x603, 8));
        assert_eq!(f.data, [0x2F, 0x60, 0x60, 0x00, 10, 0, 0, 0]);
        let heartbeat = SdoRequest::Write { object: Object { index: 0x1017, sub: 0 }, value: 100, size: 2 };
        assert_eq!(heartbeat.frame(node(3)).data, [0x2B, 0x17, 0x10, 0x00, 100, 0, 0, 0]);
        let cob = SdoRequest::Write { object: Object { index: 0x1400, sub: 1 }, value: 0x8000_0203, size: 4 };
        assert_eq!(cob.frame(node(3)).data, [0x23, 0x00, 0x14, 0x01, 0x03, 0x02, 0x00, 0x80]);
        let read = SdoRequest::Read(Object { index: 0x1018, sub: 2 });
        assert_eq!(read.frame(node(3)).data, [0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]);
    }

    #[test]
    fn sdo_replies_are_matched_to_their_request() {
        let read = SdoRequest::Read(Object { index: 0x1000, sub: 0 });
        let reply = |id, data| CanFrame { id, len: 8, data };
        // Device type 0x00020192: CiA 402 (0x192 = 402) in the low 16 bits.
        let answer = reply(0x583, [0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]);
        assert_eq!(sdo_reply(&answer, node(3), &read), Some(Ok(SdoReply::Read { value: 0x0002_0192, size: Some(4) })));
        // One byte (0x6061, the mode display: 10), with garbage beyond the size masked off.
        let mode = SdoRequest::Read(Object { index: 0x6061, sub: 0 });
        let answer = reply(0x583, [0x4F, 0x61, 0x60, 0x00, 10, 0xEE, 0xEE, 0xEE]);
        assert_eq!(sdo_reply(&answer, node(3), &mode), Some(Ok(SdoReply::Read { value: 10, size: Some(1) })));
        // Another node's reply, or another object's, is not this transfer's.
        assert_eq!(sdo_reply(&answer, node(4), &mode), None);
        assert_eq!(sdo_reply(&reply(0x583, [0x4F, 0x60, 0x60, 0, 10, 0, 0, 0]), node(3), &mode), None);
        let write = SdoRequest::Write { object: Object { index: 0x6060, sub: 0 }, value: 10, size: 1 };
        let ack = reply(0x583, [0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0]);
        assert_eq!(sdo_reply(&ack, node(3), &write), Some(Ok(SdoReply::Written)));
        // A drive without CST refuses the value: abort 0x06090030.
        let abort = reply(0x583, [0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06]);
        let Some(Err(e)) = sdo_reply(&abort, node(3), &write) else { panic!("an abort is an error") };
        assert_eq!(e, SdoError::Aborted { node: node(3), object: write.object(), code: 0x0609_0030 });
        assert!(e.to_string().contains("invalid value for parameter") && e.to_string().contains("0x6060:0"), "{e}");
        // An upload answered as a download, and a segmented upload.
        assert!(matches!(sdo_reply(&ack, node(3), &SdoRequest::Read(write.object())), Some(Err(_))));
        let segmented = reply(0x583, [0x41, 0x60, 0x60, 0x00, 20, 0, 0, 0]);
        let read_mode = SdoRequest::Read(write.object());
        assert!(matches!(sdo_reply(&segmented, node(3), &read_mode), Some(Err(SdoError::Segmented { .. }))));
    }

    /// RPDO1 = {0x6040 controlword, 0x6071 target torque}: entries 0x60400010 and 0x60710010,
    /// written between an invalidated and a revalidated COB-ID, count last.
    #[test]
    fn a_pdo_is_mapped_in_the_standards_order() {
        let objects = [(Object { index: 0x6040, sub: 0 }, 16), (Object { index: 0x6071, sub: 0 }, 16)];
        let written: Vec<(u16, u8, u32)> = map_pdo(0x1400, 0x1600, RPDO1_BASE + 3, &objects)
            .map(|s| match s {
                SdoRequest::Write { object, value, .. } => (object.index, object.sub, value),
                SdoRequest::Read(_) => unreachable!(),
            })
            .collect();
        assert_eq!(
            written,
            [
                (0x1400, 1, 0x8000_0203),
                (0x1600, 0, 0),
                (0x1600, 1, 0x6040_0010),
                (0x1600, 2, 0x6071_0010),
                (0x1600, 0, 2),
                (0x1400, 2, 1),
                (0x1400, 1, 0x203),
            ]
        );
    }
}
