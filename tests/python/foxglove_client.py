"""Clients of the daemon's live stream, written from the Foxglove WebSocket protocol's spec
(github.com/foxglove/ws-protocol, docs/spec.md) on the `websockets` library and protobuf, not on
arash's code: a reading client that decodes each message with the schema the server advertised,
and a stuck client that subscribes and then never reads.

Run as a script, `python foxglove_client.py stuck HOST:PORT SECONDS`, it is the stuck client of
bench/daemon_soak.sh."""

import base64
import json
import os
import socket
import struct
import sys
import time

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

SUBPROTOCOL = "foxglove.sdk.v1"


def message_classes(channels):
    """Channel id -> a decoder of that channel's payloads, from the advertised schemas."""
    decoders = {}
    for c in channels:
        if c["encoding"] == "protobuf":
            files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(c["schema"]))
            pool = descriptor_pool.DescriptorPool()
            for f in files.file:
                pool.Add(f)
            cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(c["schemaName"]))
            decoders[c["id"]] = cls.FromString
        elif c["encoding"] == "json":
            decoders[c["id"]] = lambda data: json.loads(data)
        else:
            raise AssertionError(f"unexpected encoding {c['encoding']} on {c['topic']}")
    return decoders


def subscribe_all(channels):
    return json.dumps({"op": "subscribe", "subscriptions": [{"id": 100 + c["id"], "channelId": c["id"]}
                                                             for c in channels]})


def parse_message_data(frame):
    """(subscription id, log time ns, payload) of a binary `message data` frame (opcode 1)."""
    opcode, subscription, log_time = struct.unpack_from("<BIQ", frame)
    assert opcode == 1, opcode
    return subscription, log_time, frame[13:]


class Reader:
    """Connects, reads serverInfo and advertise, subscribes to every channel and collects what
    arrives: {topic: [(log time ns, wall time s, decoded message)]}."""

    def __init__(self, address):
        from websockets.sync.client import connect
        self.connection = connect(f"ws://{address}", subprotocols=[SUBPROTOCOL], max_size=None)
        self.ws = self.connection.__enter__()
        assert self.ws.subprotocol == SUBPROTOCOL
        self.info = json.loads(self.ws.recv(timeout=5))
        advertise = json.loads(self.ws.recv(timeout=5))
        assert (self.info["op"], advertise["op"]) == ("serverInfo", "advertise")
        self.channels = {c["id"]: c for c in advertise["channels"]}
        self.decoders = message_classes(advertise["channels"])
        self.ws.send(subscribe_all(advertise["channels"]))
        self.received = {c["topic"]: [] for c in advertise["channels"]}

    def collect(self, seconds):
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            try:
                frame = self.ws.recv(timeout=left)
            except TimeoutError:
                break
            assert isinstance(frame, bytes), frame
            subscription, log_time, payload = parse_message_data(frame)
            channel = self.channels[subscription - 100]
            message = self.decoders[channel["id"]](payload)
            self.received[channel["topic"]].append((log_time, time.monotonic(), message))
        return self.received

    def close(self):
        self.connection.__exit__(None, None, None)


class Stuck:
    """A client that completes the handshake, subscribes to everything and then reads nothing,
    with a small receive buffer so that the server's side fills soon."""

    def __init__(self, address):
        host, port = address.rsplit(":", 1)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        self.sock.connect((host, int(port)))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET / HTTP/1.1\r\nHost: {address}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                           f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                           f"Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n").encode())
        response = b""
        while b"\r\n\r\n" not in response:
            response += self.sock.recv(1)
        assert response.startswith(b"HTTP/1.1 101"), response
        # serverInfo and advertise: text frames, read whole (their lengths are in their headers).
        channels = None
        while channels is None:
            text = json.loads(self._frame())
            if text["op"] == "advertise":
                channels = text["channels"]
        self._send_text(subscribe_all(channels))

    def _exactly(self, n):
        data = b""
        while len(data) < n:
            data += self.sock.recv(n - len(data))
        return data

    def _frame(self):
        b0, b1 = self._exactly(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._exactly(2))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._exactly(8))[0]
        return self._exactly(n)

    def _send_text(self, text):
        data, mask = text.encode(), os.urandom(4)
        header = bytes([0x81]) + (bytes([0x80 | 126]) + struct.pack(">H", len(data)) if len(data) >= 126
                                  else bytes([0x80 | len(data)]))
        self.sock.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))

    def close(self):
        self.sock.close()


if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] != "stuck":
        sys.exit("usage: foxglove_client.py stuck HOST:PORT SECONDS")
    client = Stuck(sys.argv[2])
    time.sleep(float(sys.argv[3]))
    client.close()
