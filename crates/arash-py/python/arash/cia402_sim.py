"""CiA 402 drives on a simulated CAN bus, reached through a pseudo-terminal that plays an slcan
(Lawicel) USB adapter: the independent far end of arash's CANopen master, for its tests and for
``arash demo --link canopen`` (``python -m arash.cia402_sim`` serves the simulated rig, as
``arash mock-motor`` does over arash's own protocol). Needs python-can and canopen
(``pip install python-can canopen``).

Written from the standards (CiA 301 for the object dictionary, SDO, NMT, heartbeat and EMCY; CiA
402 for the drive's state machine and cyclic synchronous torque mode), not from arash's code:
the `canopen` package serves each drive's object dictionary over SDO (a ``LocalNode`` per
drive), answers NMT and produces the heartbeat and emergencies; python-can's virtual bus
carries the frames. What `canopen` has no slave for is ours here: the CiA 402 state machine,
the process data by the mapping the master wrote, the consumer heartbeat and its abort
reaction (0x1016, 0x6007), and a plant behind the drives.

A drive answers each SYNC within the cycle: it applies the target received before the SYNC and
sends its TPDO at once. Here the process data (SYNC and RPDOs) are handled on the adapter's own
thread as the host's line arrives, not through the virtual bus and canopen's notifier thread,
which answered one to three cycles late and made the paper's robust law swing. SDO, NMT,
heartbeats and EMCY go through the bus.

Fault injection: a silent heartbeat, an EMCY, a drive fault, dropped TPDOs, a drive that stops
by itself (its quick-stop input: quick stop active, then switch on disabled; safe torque off:
straight to switch on disabled), a reboot with its boot-up message (the object dictionary back
to its defaults, the PDO mapping lost), another master's NMT command, a bus-off adapter that
refuses every frame, one adapter error (BEL), adapter status flags answered to the next ``F``,
lines that are not the protocol, and at construction a drive that ignores the mode, one without
CST, one whose PDOs hold fewer objects, one that is not a CiA 402 drive, nodes that do not answer
and drives slow to answer SDOs. A drive's watch on the master's heartbeat (0x1016) starts with
the first beat it sees (CiA 301), or, as some drives do, as soon as 0x1016 is written.
"""

from __future__ import annotations

import argparse
import array
import gc
import json
import math
import os
import select
import signal
import struct
import sys
import threading
import time
import tty
from dataclasses import dataclass, field

try:
    import can
    import canopen
    from canopen.objectdictionary import (INTEGER8, INTEGER16, INTEGER32, UNSIGNED8, UNSIGNED16, UNSIGNED32,
                                          ODArray, ODRecord, ODVariable, ObjectDictionary)
    from canopen.sdo import SdoAbortedError
except ImportError as _missing:
    raise ImportError(
        f"arash.cia402_sim needs python-can and canopen ({_missing.name} is not installed): pip install 'arash[sim]'"
    ) from _missing

# Statuswords of CiA 402's states (bit 9 "remote" set, as drives under a master report it).
SWITCH_ON_DISABLED = 0x0250
READY_TO_SWITCH_ON = 0x0231
SWITCHED_ON = 0x0233
OPERATION_ENABLED = 0x1237  # bit 12: the drive follows the target in the cyclic synchronous modes
QUICK_STOP_ACTIVE = 0x0217
FAULT = 0x0218

CST = 10
CST_SUPPORTED = 1 << 9
ALL_CSP_CSV_CST = (1 << 7) | (1 << 8) | CST_SUPPORTED
CIA402_DEVICE = 0x00020192

# The abort codes of CiA 301 the drives use.
MAPPING_TOO_LONG = 0x06040042
CANNOT_MAP = 0x06040041
INCOMPATIBLE = 0x06040043
INVALID_VALUE = 0x06090030


@dataclass
class DriveSpec:
    """One drive: its node ID, its motor's ratings and what is wrong with it."""
    node: int
    rated_current_ma: int = 5000
    rated_torque_mnm: int = 138
    # Joint torque per ampere (N·m/A or N/A) and encoder counts per joint unit (rad or m): the
    # motor and transmission between the drive and the plant.
    joint_torque_per_amp: float = 0.3312
    counts_per_unit: float = 8192 / (2 * 3.141592653589793 * 0.08333333333333333)
    device_type: int = CIA402_DEVICE
    supported_modes: int = ALL_CSP_CSV_CST
    ignores_mode: bool = False
    max_mapped: int = 8
    answers: bool = True
    serial: int | None = None  # 0x1018:4; default the node ID
    # Seconds each SDO answer is held back (a drive busy with its own work).
    sdo_delay_s: float = 0.0
    # When the watch on the master's heartbeat starts: "first-beat" (CiA 301: the first beat
    # received after 0x1016 is set) or "write" (the moment 0x1016 is written).
    watch_starts: str = "first-beat"
    # The quick-stop option code (0x605A): 2, quick stop then switch on disabled; 6, stay in
    # quick stop active.
    quick_stop_option: int = 2
    # Seconds from "enable operation" in switched on to operation enabled: a drive that releases
    # its motor's brake first (typically 50–300 ms) reports switched on meanwhile.
    brake_release_s: float = 0.0


@dataclass
class Injected:
    """Faults switched on while the drive runs."""
    silent_heartbeat: bool = False
    drop_tpdos: bool = False
    # The drive's quick-stop input is held (an e-stop wired to it): the drive will not leave
    # switch on disabled while it is.
    quick_stop_input: bool = False


def _var(name, index, sub, data_type, access="rw", default=None):
    v = ODVariable(name, index, sub)
    v.data_type, v.access_type, v.default = data_type, access, default
    return v


def object_dictionary(spec: DriveSpec) -> ObjectDictionary:
    """The objects a CST drive has (CiA 301 communication area, CiA 402 device profile)."""
    od = ObjectDictionary()
    for index, name, data_type, access, default in [
        (0x1000, "device type", UNSIGNED32, "ro", spec.device_type),
        (0x1001, "error register", UNSIGNED8, "ro", 0),
        (0x1006, "communication cycle period", UNSIGNED32, "rw", 0),
        (0x1017, "producer heartbeat time", UNSIGNED16, "rw", 0),
        (0x6007, "abort connection option code", INTEGER16, "rw", 1),
        (0x6040, "controlword", UNSIGNED16, "rw", 0),
        (0x6041, "statusword", UNSIGNED16, "ro", SWITCH_ON_DISABLED),
        (0x6060, "modes of operation", INTEGER8, "rw", 0),
        (0x6061, "modes of operation display", INTEGER8, "ro", 0),
        (0x6064, "position actual value", INTEGER32, "ro", 0),
        (0x6071, "target torque", INTEGER16, "rw", 0),
        (0x6072, "max torque", UNSIGNED16, "rw", 1000),
        (0x6075, "motor rated current", UNSIGNED32, "rw", spec.rated_current_ma),
        (0x6076, "motor rated torque", UNSIGNED32, "rw", spec.rated_torque_mnm),
        (0x6077, "torque actual value", INTEGER16, "ro", 0),
        (0x6502, "supported drive modes", UNSIGNED32, "ro", spec.supported_modes),
    ]:
        od.add_object(_var(name, index, 0, data_type, access, default))
    consumer = ODArray("consumer heartbeat time", 0x1016)
    consumer.add_member(_var("number of entries", 0x1016, 0, UNSIGNED8, "ro", 1))
    consumer.add_member(_var("consumer heartbeat time 1", 0x1016, 1, UNSIGNED32, "rw", 0))
    od.add_object(consumer)
    identity = ODRecord("identity", 0x1018)
    for sub, name, default in [(0, "highest sub-index", 4), (1, "vendor-ID", 0x000000FB),
                               (2, "product code", 0x00402402), (3, "revision", 1),
                               (4, "serial number", spec.node if spec.serial is None else spec.serial)]:
        identity.add_member(_var(name, 0x1018, sub, UNSIGNED8 if sub == 0 else UNSIGNED32, "ro", default))
    od.add_object(identity)
    for communication, mapping, base in [(0x1400, 0x1600, 0x200), (0x1800, 0x1A00, 0x180)]:
        comm = ODRecord(f"PDO communication {communication:#x}", communication)
        comm.add_member(_var("highest sub-index", communication, 0, UNSIGNED8, "ro", 2))
        comm.add_member(_var("COB-ID", communication, 1, UNSIGNED32, "rw", (1 << 31) | (base + spec.node)))
        comm.add_member(_var("transmission type", communication, 2, UNSIGNED8, "rw", 255))
        od.add_object(comm)
        entries = ODRecord(f"PDO mapping {mapping:#x}", mapping)
        entries.add_member(_var("number of mapped objects", mapping, 0, UNSIGNED8, "rw", 0))
        for sub in range(1, 9):
            entries.add_member(_var(f"mapped object {sub}", mapping, sub, UNSIGNED32, "rw", 0))
        od.add_object(entries)
    return od


MAPPABLE_RX = {0x6040, 0x6071}
MAPPABLE_TX = {0x6041, 0x6064, 0x6077}


class Drive:
    """One CiA 402 drive in CST: a LocalNode for the communication, the state machine and the
    process data here. The plant is stepped by the simulator at each SYNC."""

    def __init__(self, spec: DriveSpec, network: canopen.Network, log):
        self.spec = spec
        self.node = canopen.LocalNode(spec.node, object_dictionary(spec))
        self.injected = Injected()
        self.log = log
        self.state = SWITCH_ON_DISABLED
        self.controlword = 0
        self.target = 0
        self.torque = 0
        self.mode_display = 0
        self.position = 0
        self.host_seen = None
        self.lock = threading.Lock()
        if spec.answers and spec.node in network.nodes:
            # A second device at a node ID already on the bus: canopen's Network keeps one node
            # per ID, so this one is put on the bus beside it, where both answer.
            self.node.associate_network(network)
        elif spec.answers:
            network.add_node(self.node)
        if spec.answers:
            self.node.add_write_callback(self._on_write)
            self.node.add_read_callback(self._on_read)
            self.node.nmt.state = "PRE-OPERATIONAL"
        self.heartbeat_ms = 100
        self.last_beat = 0.0
        # When 0x1016 was last written (time.monotonic), for the watch that starts then.
        self.consumer_written = None
        # A quick stop from the drive's own input ends in switch on disabled at this time.
        self.quick_stop_ends = None
        # Operation is enabled at this time, once the brake has released (spec.brake_release_s).
        self.brake_released_at = None

    # --- the object dictionary -------------------------------------------------------------
    def stored(self, index, sub=0):
        """An object's value as the master last wrote it, or its default."""
        obj = self.node.object_dictionary[index]
        obj = obj if isinstance(obj, ODVariable) else obj[sub]
        try:
            return obj.decode_raw(self.node.data_store[index][sub])
        except KeyError:
            return obj.default

    def _on_read(self, index, subindex, od):
        if self.spec.sdo_delay_s:
            time.sleep(self.spec.sdo_delay_s)
        live = {0x6041: self.state, 0x6061: self.mode_display, 0x6064: self.position, 0x6077: self.torque,
                0x6040: self.controlword}
        return live.get(index)

    def _on_write(self, index, subindex, od, data):
        if self.spec.sdo_delay_s:
            time.sleep(self.spec.sdo_delay_s)
        value = od.decode_raw(data)
        self.log.append(("sdo-write", self.spec.node, index, subindex, value))
        if index == 0x1016:
            self.consumer_written = time.monotonic()
        if index == 0x1017:
            # The simulator's clock thread produces the heartbeat (see Simulator._clock), not
            # canopen's own timer thread, which a loaded host can stall.
            self.node.nmt.stop_heartbeat()
            self.heartbeat_ms = value
        elif index in (0x1600, 0x1A00):
            self._check_mapping(index, subindex, value)
        elif index == 0x6060:
            if value == CST and not self.spec.supported_modes & CST_SUPPORTED:
                raise SdoAbortedError(INVALID_VALUE)
            if not self.spec.ignores_mode:
                self.mode_display = value
        elif index == 0x6040:
            self._command(value)

    def _check_mapping(self, index, sub, value):
        communication = 0x1400 if index == 0x1600 else 0x1800
        if not self.stored(communication, 1) & (1 << 31):
            raise SdoAbortedError(INCOMPATIBLE)  # a valid PDO's mapping is not changed
        if sub == 0:
            if value > self.spec.max_mapped:
                raise SdoAbortedError(MAPPING_TOO_LONG)
            bits = sum(self.stored(index, s) & 0xFF for s in range(1, value + 1))
            if bits > 64:
                raise SdoAbortedError(MAPPING_TOO_LONG)
        elif value >> 16 not in (MAPPABLE_RX if index == 0x1600 else MAPPABLE_TX):
            raise SdoAbortedError(CANNOT_MAP)

    def mapping(self, index):
        return [self.stored(index, s) for s in range(1, self.stored(index, 0) + 1)]

    # --- CiA 402 ---------------------------------------------------------------------------
    def _command(self, word):
        """The state machine of CiA 402's figure 8, one controlword at a time."""
        with self.lock:
            previous, self.controlword = self.controlword, word
            s = self.state
            if s == FAULT:
                if word & 0x80 and not previous & 0x80:
                    self.state = SWITCH_ON_DISABLED
                return
            if word & 0x02 == 0:  # disable voltage
                self.state = SWITCH_ON_DISABLED
            elif word & 0x04 == 0:  # quick stop
                self.state = QUICK_STOP_ACTIVE if s == OPERATION_ENABLED else SWITCH_ON_DISABLED
            elif word & 0x8F == 0x06:  # shutdown
                if s == SWITCH_ON_DISABLED and self.injected.quick_stop_input:
                    return  # the input holds the drive off
                if s in (SWITCH_ON_DISABLED, SWITCHED_ON, OPERATION_ENABLED):
                    self.state = READY_TO_SWITCH_ON
            elif word & 0x8F == 0x07:  # switch on, or disable operation
                if s in (READY_TO_SWITCH_ON, OPERATION_ENABLED):
                    self.state = SWITCHED_ON
            elif word & 0x8F == 0x0F:  # enable operation (from ready: switch on first)
                if s == READY_TO_SWITCH_ON:
                    self.state = SWITCHED_ON
                elif s == SWITCHED_ON and self.mode_display == CST:
                    if not self.spec.brake_release_s:
                        self.state = OPERATION_ENABLED
                    elif self.brake_released_at is None:
                        self.brake_released_at = time.monotonic() + self.spec.brake_release_s
            if self.state != SWITCHED_ON or word & 0x8F != 0x0F:
                self.brake_released_at = None  # the enable was withdrawn, or has happened

    NMT_STATES = {"INITIALISING": 0x00, "STOPPED": 0x04, "OPERATIONAL": 0x05, "PRE-OPERATIONAL": 0x7F}

    def heartbeat(self, now):
        """The heartbeat frame (COB-ID and data) if one is due at ``now``."""
        if not self.spec.answers or self.injected.silent_heartbeat or not self.heartbeat_ms:
            return None
        if now - self.last_beat < self.heartbeat_ms / 1000:
            return None
        self.last_beat = now
        return 0x700 + self.spec.node, bytes([self.NMT_STATES.get(self.node.nmt.state, 0x7F)])

    def fault(self, code=0x2310):
        """An internal fault: the drive drops its torque, reports it and sends an EMCY."""
        with self.lock:
            self.state = FAULT
            self.torque = 0
        self.node.emcy.send(code, 0x03)

    def quick_stop_from_input(self, held=True):
        """The drive's own quick-stop input (an e-stop wired to it): from operation enabled to
        quick stop active, the torque dropped, then by the quick-stop option code to switch on
        disabled a few milliseconds later. No fault bit, no EMCY: nothing the master commanded."""
        with self.lock:
            self.injected.quick_stop_input = held
            if self.state == OPERATION_ENABLED:
                self.state = QUICK_STOP_ACTIVE
                self.torque = 0
                if self.spec.quick_stop_option in (1, 2, 3, 4):
                    self.quick_stop_ends = time.monotonic() + 0.005

    def release_quick_stop_input(self):
        self.injected.quick_stop_input = False

    def switch_off_by_itself(self):
        """Safe torque off on many drives: from any enabled state straight to switch on disabled,
        with no fault bit."""
        with self.lock:
            if self.state in (OPERATION_ENABLED, SWITCHED_ON, READY_TO_SWITCH_ON):
                self.state = SWITCH_ON_DISABLED
                self.torque = 0

    def advance(self, now):
        """The drive's own timed transitions: a quick stop's end, a brake's release."""
        with self.lock:
            if self.brake_released_at is not None and now >= self.brake_released_at:
                self.brake_released_at = None
                if self.state == SWITCHED_ON:
                    self.state = OPERATION_ENABLED
            if self.quick_stop_ends is not None and now >= self.quick_stop_ends:
                self.quick_stop_ends = None
                if self.state == QUICK_STOP_ACTIVE:
                    self.state = SWITCH_ON_DISABLED

    def reboot(self):
        """A power cycle or a reset: the object dictionary back to its defaults (the master's
        PDO mapping, mode, watchdogs and heartbeat lost), the state machine in switch on
        disabled, NMT pre-operational, and the boot-up message (CiA 301, 7.2.8.3.3)."""
        with self.lock:
            self.node.data_store.clear()
            self.state, self.controlword, self.target, self.torque = SWITCH_ON_DISABLED, 0, 0, 0
            self.mode_display = 0
            self.heartbeat_ms = 0
            self.consumer_written = None
            self.quick_stop_ends = None
            self.brake_released_at = None
        self.node.nmt.state = "PRE-OPERATIONAL"
        self.node.network.send_message(0x700 + self.spec.node, bytes([0x00]))

    def abort_connection(self):
        """The reaction of 0x6007 when the master's heartbeat is lost."""
        option = self.stored(0x6007)
        self.node.emcy.send(0x8130, 0x11)
        with self.lock:
            if option == 1:
                self.state = FAULT
            elif self.state in (OPERATION_ENABLED, SWITCHED_ON, READY_TO_SWITCH_ON, QUICK_STOP_ACTIVE):
                self.state = SWITCH_ON_DISABLED
            self.torque = 0

    def on_rpdo(self, data):
        """RPDO1 by the mapping the master wrote (the adapter's thread, see Simulator._fast)."""
        with self.lock:  # see tpdo: not half a mapping across a reboot
            if self.node.nmt.state != "OPERATIONAL" or self.stored(0x1400, 1) & (1 << 31):
                return
            entries = self.mapping(0x1600)
        offset = 0
        for entry in entries:
            index, bits = entry >> 16, entry & 0xFF
            chunk = bytes(data[offset // 8:(offset + bits) // 8])
            value = int.from_bytes(chunk, "little", signed=index == 0x6071)
            offset += bits
            if index == 0x6040:
                if value != self.controlword:
                    self._command(value)
            elif index == 0x6071:
                self.target = value

    def joint_torque(self):
        """The torque the motor applies to the plant (joint side), from the target at this SYNC."""
        with self.lock:
            if self.state != OPERATION_ENABLED:
                self.torque = 0
            else:
                limit = self.stored(0x6072)
                self.torque = max(-limit, min(limit, self.target))
            amps = self.torque / 1000 * self.spec.rated_current_ma / 1000
        return amps * self.spec.joint_torque_per_amp

    def sense(self, position, torque):
        """The plant's state at this SYNC: the joint's position (rad or m) and, where the plant
        senses it, the joint torque its current makes (0x6077 then reports it, in ‰ of the rated
        current; otherwise the target applied)."""
        self.position = int(round(position * self.spec.counts_per_unit))
        if torque is not None:
            amps = torque / self.spec.joint_torque_per_amp if self.state == OPERATION_ENABLED else 0.0
            self.torque = max(-32768, min(32767, int(round(amps / self.spec.rated_current_ma * 1e6))))

    def tpdo(self):
        """TPDO1 by the mapping the master wrote, or None when it is not to be sent."""
        # Under the lock: a reboot (the test's thread) clears the object dictionary, and a
        # mapping read half before and half after it names object 0.
        with self.lock:
            cob_id = self.stored(0x1800, 1)
            if self.node.nmt.state != "OPERATIONAL" or cob_id & (1 << 31) or self.injected.drop_tpdos:
                return None
            values = {0x6041: (self.state, "<H"), 0x6064: (self.position, "<i"), 0x6077: (self.torque, "<h")}
            entries = self.mapping(0x1A00)
            payload = b"".join(struct.pack(values[e >> 16][1], values[e >> 16][0]) for e in entries)
        return cob_id & 0x7FF, payload


# The drives answer each SYNC within a cycle on real hardware. Here the threads that carry the
# frames and step the plant run at a real-time priority below the daemon's (80) where the host
# allows it, and Python switches threads every 0.2 ms instead of 5, so that a loaded test host
# does not stall the drives past the master's link timeout.
SIM_PRIORITY = 70
# The bus's bit rate, for its load (docs/canopen.md: 1 Mbit/s).
BIT_RATE = 1_000_000
SWITCH_INTERVAL_S = 2e-4
# The most one tick of the drives' clock thread counts towards a watchdog (s): the thread wakes
# every millisecond, and a longer gap is the host holding the simulator, not time on the drives.
CLOCK_TICK_MAX_S = 0.005


def real_time_thread():
    """Raise the calling thread to SCHED_FIFO at SIM_PRIORITY; ordinary scheduling if refused."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(SIM_PRIORITY))
    except (PermissionError, OSError):
        pass


def frame_bits(ident, data):
    """The bits a data frame with an 11-bit identifier takes on the bus: its fields from the
    start of frame to the CRC with the stuff bits they get (one after five equal bits, CAN
    2.0A), then the CRC delimiter, acknowledgement, end of frame and intermission (13 bits)."""
    bits = [0] + [ident >> (10 - i) & 1 for i in range(11)] + [0, 0, 0]  # SOF, ID, RTR, IDE, r0
    bits += [len(data) >> (3 - i) & 1 for i in range(4)]
    bits += [byte >> (7 - i) & 1 for byte in data for i in range(8)]
    crc = 0
    for b in bits:
        crc = ((crc << 1) ^ (0x4599 if (crc >> 14) ^ b else 0)) & 0x7FFF
    bits += [crc >> (14 - i) & 1 for i in range(15)]
    stuffed, run, last = 0, 0, None
    for b in bits:
        run = run + 1 if b == last else 1
        last = b
        if run == 5:
            stuffed += 1
            run, last = 1, 1 - b  # the stuff bit starts the next run
    return len(bits) + stuffed + 13


# A data frame's bits without stuff bits besides its data: 47 (docs/canopen.md).
NOMINAL_BITS = 47
# One frame in this many has its stuff bits counted; a prime, so that the sample does not lock
# onto one frame of the cycle's fixed pattern (RPDOs, SYNC, TPDOs).
STUFF_SAMPLE = 61


class SlcanAdapter:
    """A pseudo-terminal that answers as an slcan USB adapter: `O`, `C`, `Sn` and `F` commands,
    `t` frames onto the bus and the bus's frames back as `t` lines."""

    def __init__(self, bus: can.BusABC, fast=None, record=True):
        self.bus = bus
        # fast(ident, data): the frames to answer a host frame with at once, or None to put it
        # on the bus.
        self.fast = fast
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self.open = False
        self.bus_off = False
        # Status flags the next `F` answers with (then cleared, as reading them clears them on
        # an SJA1000-based adapter); bus-off answers error passive and bus error every time.
        self.status_flags = 0
        self.status_requests = 0
        # (time, id, bytes) the host put on the bus, when recorded
        self.sent: list[tuple[float, int, bytes]] | None = [] if record else None
        self.bits = 0  # on the bus, both ways (count_frame)
        self.frames = 0
        self._write_lock = threading.Lock()
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._from_host, daemon=True),
                         threading.Thread(target=self._to_host, daemon=True)]
        for t in self._threads:
            t.start()

    def count_frame(self, ident, data):
        """A frame's bits on the bus: exactly without stuff bits, and the stuff bits of every
        STUFF_SAMPLE-th frame counted for all of them (frame_bits costs some 20 µs of the
        thread that answers the SYNC; counting every frame made answers late)."""
        self.bits += NOMINAL_BITS + 8 * len(data)
        self.frames += 1
        if self.frames % STUFF_SAMPLE == 0:
            self.bits += STUFF_SAMPLE * (frame_bits(ident, data) - NOMINAL_BITS - 8 * len(data))

    def _write(self, data: bytes):
        with self._write_lock:
            try:
                os.write(self.master, data)
            except OSError:
                pass

    def adapter_error(self):
        """One BEL, as an adapter sends when it refuses a command or frame."""
        self._write(b"\a")

    def report_status(self, flags):
        """Answer the host's next status request (`F`) with ``flags`` (bit 5 error passive, bit 7
        bus error, bit 3 data overrun, ...)."""
        self.status_flags |= flags

    def send_raw(self, data: bytes):
        """Bytes to the host as the adapter's own: lines that are not its protocol, frames of
        other kinds."""
        self._write(data)

    def _line(self, line: bytes):
        if not line:
            return
        kind = line[:1]
        if kind == b"t":
            if self.bus_off or not self.open:
                self._write(b"\a")
                return
            ident, length = int(line[1:4], 16), int(line[4:5])
            data = bytes.fromhex(line[5:5 + 2 * length].decode())
            if self.sent is not None:
                self.sent.append((time.monotonic(), ident, data))
            self.count_frame(ident, data)
            answer = self.fast(ident, data) if self.fast else None
            for i, d in answer or ():
                self.count_frame(i, d)
            if answer is None:
                self.bus.send(can.Message(arbitration_id=ident, data=data, is_extended_id=False))
            self._write(b"z\r" + b"".join(self.frame_line(i, d) for i, d in answer or ()))
        elif kind in (b"O", b"C", b"S"):
            self.open = kind == b"O" or (self.open and kind == b"S")
            self._write(b"\r")
        elif kind == b"F":
            self.status_requests += 1
            flags, self.status_flags = self.status_flags | (0xA0 if self.bus_off else 0), 0
            self._write(b"F%02X\r" % flags)
        else:
            self._write(b"\a")

    def _from_host(self):
        real_time_thread()
        pending = b""
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            try:
                pending += os.read(self.master, 4096)
            except OSError:
                time.sleep(0.01)
                continue
            *lines, pending = pending.split(b"\r")
            for line in lines:
                self._line(line)

    def _to_host(self):
        real_time_thread()
        while not self._stop.is_set():
            message = self.bus.recv(0.05)
            if message is None or self.bus_off or not self.open:
                continue
            data = bytes(message.data)
            self.count_frame(message.arbitration_id, data)
            self._write(self.frame_line(message.arbitration_id, data))

    @staticmethod
    def frame_line(ident, data):
        return b"t%03X%d%s\r" % (ident, len(data), data.hex().upper().encode())

    def close(self):
        self._stop.set()
        for t in self._threads:
            t.join(1)
        self.bus.shutdown()
        os.close(self.master)
        os.close(self._slave)


@dataclass
class Plant:
    """The joints behind the drives: ``step(q, qd, tau, dt)`` returns the next (q, qd). A drive
    that is not enabled holds its joint's brake, as drives of arms under gravity do."""
    step: object
    q: list = field(default_factory=list)
    qd: list = field(default_factory=list)

    def cycle(self, tau, enabled, dt):
        """One SYNC period: the joints' positions, and no sensed torque."""
        q, qd = self.step(self.q, self.qd, tau, dt)
        q, qd = list(q), list(qd)
        for j, on in enumerate(enabled):
            if not on:
                q[j], qd[j] = self.q[j], 0.0
        self.q, self.qd = q, qd
        return q, None


class RigPlant:
    """arash's simulated rig behind the drives (``arash.SimulatedMotors``: the plant, encoders
    and current sensing that ``arash mock-motor`` serves), so that a run through CiA 402 and one
    through arash's serial protocol drive the same rig. Like the mock's power stage it moves only
    while every drive is enabled."""

    def __init__(self, motors, resolution, truth=None):
        self.motors, self.resolution = motors, list(resolution)
        # Each powered cycle's truth as ``arash mock-motor --truth`` writes it, flushed every
        # 100 cycles so that a reader following the file lags little.
        self.truth, self._rows = truth, 0
        if truth is not None:
            truth.write(motors.truth_header() + "\n")
            truth.flush()

    def cycle(self, tau, enabled, dt):
        n = len(self.resolution)
        if all(enabled):
            self.motors.apply(dt, list(tau))
            torque = self.motors.measured_torque()
            if self.truth is not None:
                self.truth.write(self.motors.truth_row() + "\n")
                self._rows += 1
                if self._rows % 100 == 0:
                    self.truth.flush()
        else:
            torque = [0.0] * n
        counts = self.motors.encoder_counts()
        return [c * r for c, r in zip(counts, self.resolution)], torque


class Simulator:
    """Drives (one per ``DriveSpec``) on a virtual CAN bus, an slcan adapter on a pty, and a
    plant stepped at each SYNC by the SYNC period the master wrote (0x1006)."""

    def __init__(self, specs, plant: Plant, channel=None, record=True):
        channel = channel or f"arash-cia402-{os.getpid()}-{id(self)}"
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        # A full collection in a test process that holds much (a whole suite's imports and
        # data) holds the interpreter for tens of milliseconds: the drives would stop answering
        # and heartbeating. The simulator makes little garbage; collections wait until close.
        self._collecting = gc.isenabled()
        gc.disable()
        self.network = canopen.Network()
        self.network.connect(interface="virtual", channel=channel)
        self.log: list[tuple] = []
        self.drives = [Drive(s, self.network, self.log) for s in specs]
        # The drives that turn the joints, in order: the first at each node ID. A second device
        # at an ID already taken is on the bus and answers, but turns nothing.
        firsts: dict[int, Drive] = {}
        for d in self.drives:
            firsts.setdefault(d.spec.node, d)
        self.axes = list(firsts.values())
        self.plant = plant
        self._rpdo = {0x200 + d.spec.node: d for d in self.axes if d.spec.answers}
        self.adapter = SlcanAdapter(can.Bus(interface="virtual", channel=channel), fast=self._fast, record=record)
        self.syncs = 0
        self.sync_times = array.array("d")  # when each SYNC arrived (time.monotonic)
        self._master_heartbeat: dict[int, float] = {}
        # (time, node) of each drive's abort on a lost master heartbeat (0x1016, 0x6007).
        self.aborts: list[tuple[float, int]] = []
        self._notifier_raised = False
        for cob in range(0x701, 0x780):
            self.network.subscribe(cob, self._on_heartbeat)
        self._stop = threading.Event()
        self._watch = threading.Thread(target=self._clock, daemon=True)
        self._watch.start()

    @property
    def path(self):
        return self.adapter.path

    def drive(self, node) -> Drive:
        return next(d for d in self.drives if d.spec.node == node)

    def _fast(self, ident, data):
        """The process data, on the adapter's thread: an RPDO is taken, a SYNC steps the plant
        and is answered with every drive's TPDO. Anything else goes on the bus."""
        if ident == 0x080:
            return self._on_sync()
        drive = self._rpdo.get(ident)
        if drive is None:
            return None
        drive.on_rpdo(data)
        return []

    def _on_sync(self):
        self.syncs += 1
        self.sync_times.append(time.monotonic())
        period = (self.drives[0].stored(0x1006) or 1000) * 1e-6
        tau = [d.joint_torque() for d in self.axes]
        positions, torques = self.plant.cycle(tau, [d.state == OPERATION_ENABLED for d in self.axes], period)
        frames = []
        for j, d in enumerate(self.axes):
            d.sense(positions[j], None if torques is None else torques[j])
            pdo = d.tpdo()
            if pdo is not None:
                frames.append(pdo)
        return frames

    def _on_heartbeat(self, can_id, data, timestamp):
        # The network's notifier thread, which runs every callback (SDO and NMT too). It holds
        # the interpreter while it runs: at ordinary priority a busy host could preempt it
        # there and stall the drives' threads behind it.
        if not self._notifier_raised:
            real_time_thread()
            self._notifier_raised = True
        self._master_heartbeat[can_id - 0x700] = time.monotonic()

    def _clock(self):
        """Every millisecond: each drive's heartbeat when due (0x1017), and its consumer
        heartbeat (0x1016:1): from the master's first beat on, a gap longer than its time aborts
        the connection once (0x6007)."""
        real_time_thread()
        tripped = set()
        # A drive's watch on the master counts its own clock, which nothing holds up. The
        # simulator's threads share one interpreter with the test: a host that holds it (a busy
        # machine, a thread at ordinary priority preempted while it holds the GIL) delays this
        # thread and the one that records the master's beats alike, and on waking this one would
        # judge beats that arrived but were not yet recorded. So silence is counted in this
        # thread's ticks, each at most CLOCK_TICK_MAX_S, from the last beat it saw recorded.
        silence = {}
        last_seen = {}
        last = time.monotonic()
        while not self._stop.wait(0.001):
            now = time.monotonic()
            tick, last = min(now - last, CLOCK_TICK_MAX_S), now
            for d in self.drives:
                d.advance(now)
                beat = d.heartbeat(now)
                if beat is not None:
                    self.network.send_message(*beat)
            for d in self.drives:
                entry = d.stored(0x1016, 1) if d.spec.answers else 0
                master, limit_ms = entry >> 16 & 0x7F, entry & 0xFFFF
                seen = self._master_heartbeat.get(master)
                if d.spec.watch_starts == "write" and d.consumer_written is not None:
                    seen = max(seen or 0.0, d.consumer_written)
                if not limit_ms or seen is None:
                    continue
                node = d.spec.node
                if last_seen.get(node) != seen:
                    last_seen[node], silence[node] = seen, 0.0
                else:
                    silence[node] += tick
                late = silence[node] > limit_ms / 1000
                if late and node not in tripped:
                    tripped.add(node)
                    self.aborts.append((now, node))
                    d.abort_connection()
                elif not late:
                    tripped.discard(node)

    def statistics(self):
        """What the drives saw: SYNCs, their intervals (µs: median, 99th percentile, largest),
        late SYNCs (an interval over 1.5 periods of 0x1006: a cycle the drives held the old
        target) and the bus load (the bits of every frame over the bit rate and the time), and
        the bits per SYNC, which cycles the host missed do not lower."""
        times = self.sync_times
        period_us = (self.drives[0].stored(0x1006) or 1000)
        gaps = sorted((b - a) * 1e6 for a, b in zip(times, times[1:]))
        span = times[-1] - times[0] if len(times) > 1 else 0.0
        quantile = (lambda f: round(gaps[min(len(gaps) - 1, int(f * len(gaps)))], 1)) if gaps else (lambda f: None)
        return {"syncs": len(times), "sync_interval_p50_us": quantile(0.5), "sync_interval_p99_us": quantile(0.99),
                "sync_interval_max_us": round(gaps[-1], 1) if gaps else None,
                "late_syncs": sum(g > 1.5 * period_us for g in gaps),
                "bus_load_percent": round(100 * self.adapter.bits / (BIT_RATE * span), 1) if span else None,
                "bits_per_sync": round(self.adapter.bits / len(times)) if times else None}

    def silence_heartbeat(self, node):
        self.drive(node).injected.silent_heartbeat = True

    def close(self):
        self._stop.set()
        self._watch.join(1)
        self.adapter.close()
        self.network.disconnect()
        sys.setswitchinterval(self._switch_interval)
        if self._collecting:
            gc.enable()


# The rig's encoders, transmissions and motors as the daemon's [drive] table has them by default
# (deploy/daemon.toml), and the drives' rated currents (0x6075): targets are in ‰ of them.
RIG_COUNTS_PER_REV = [8192.0, 8192.0, 8192.0]
RIG_TRANSMISSION = [1 / 12, 1 / 12, 0.0025]
RIG_TORQUE_PER_AMP = [0.3312, 0.3312, 11.04]
RIG_RATED_CURRENT_MA = [5000, 5000, 1000]


def rig_simulator(scenario=None, seed=None, nodes=(1, 2, 3), record=True, truth=None):
    """The simulated ARASH:ASiST (a scenario file, or the nominal rig) behind CiA 402 drives;
    ``truth``, an open text file, receives each powered cycle's truth as CSV."""
    from . import Robot, SimulatedMotors

    text = "" if scenario is None else open(scenario, encoding="utf-8").read()
    motors = SimulatedMotors(Robot.arash_asist(), text, RIG_COUNTS_PER_REV, RIG_TRANSMISSION, seed)
    resolution = [2 * math.pi * r / c for r, c in zip(RIG_TRANSMISSION, RIG_COUNTS_PER_REV)]
    specs = [DriveSpec(node=n, joint_torque_per_amp=k, counts_per_unit=1 / res, rated_current_ma=i)
             for n, k, res, i in zip(nodes, RIG_TORQUE_PER_AMP, resolution, RIG_RATED_CURRENT_MA)]
    return Simulator(specs, RigPlant(motors, resolution, truth), record=record)


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m arash.cia402_sim",
        description="The simulated ARASH:ASiST behind three CiA 402 drives in CST, on a pseudo-terminal that "
                    "plays an slcan adapter: `arash daemon --link canopen --port <the printed path>`.")
    parser.add_argument("--scenario", help="scenario TOML of the simulated rig (default: the nominal rig)")
    parser.add_argument("--seed", type=int, help="override the scenario's seed")
    parser.add_argument("--nodes", default="1,2,3", help="the drives' node IDs, in joint order (default 1,2,3)")
    parser.add_argument("--link", help="also make this path a symbolic link to the pseudo-terminal")
    parser.add_argument("--truth", help="write the simulated rig's truth to this CSV file, a row per powered cycle "
                                        "(the columns of `arash mock-motor --truth`)")
    args = parser.parse_args(argv)
    try:
        nodes = [int(n) for n in args.nodes.split(",")]
    except ValueError:
        parser.error(f"--nodes takes node IDs separated by commas, got {args.nodes!r}")
    if len(nodes) != 3 or not all(1 <= n <= 127 for n in nodes):
        parser.error(f"--nodes takes three node IDs from 1 to 127, one per joint, got {args.nodes!r}")
    truth = open(args.truth, "w", encoding="utf-8") if args.truth else None
    sim = rig_simulator(args.scenario, args.seed, nodes, record=False, truth=truth)
    if args.link:
        if os.path.lexists(args.link):
            os.remove(args.link)
        os.symlink(sim.path, args.link)
    # This thread too takes the interpreter now and then; at ordinary priority it could be
    # preempted holding it (see Simulator._on_heartbeat).
    real_time_thread()
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    print(sim.path, flush=True)
    print(f"arash.cia402_sim: drives {nodes} serving {sim.path}; Ctrl-C to stop", file=sys.stderr, flush=True)
    try:
        while not stop.wait(0.2):
            pass
    finally:
        sim.close()
        if truth is not None:
            truth.close()
        print("arash.cia402_sim: " + json.dumps(sim.statistics()), file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
