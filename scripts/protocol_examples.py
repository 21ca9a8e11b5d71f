#!/usr/bin/env python3
"""PROTOCOL.md's host-device examples, computed from the document alone (struct, zlib.crc32 and
a COBS written from its definition), independently of mema. The tests
(`uplink::tests::protocol_examples`, `downlink::tests::protocol_examples`) check that mema emits
and reads exactly these bytes.

    python3 scripts/protocol_examples.py
"""
import struct
import zlib

SESSION = 0x5E55_1011
BOOT = 7


def cobs(raw: bytes) -> bytes:
    out = bytearray([0])
    code_at, code = 0, 1
    for b in raw:
        if b == 0:
            out[code_at] = code
            code_at, code = len(out), 1
            out.append(0)
        else:
            out.append(b)
            code += 1
            if code == 0xFF:
                out[code_at] = code
                code_at, code = len(out), 1
                out.append(0)
    out[code_at] = code
    return bytes(out)


def frame(version, kind, session, boot, number, payload=b""):
    body = struct.pack("<BBIII", version, kind, session, boot, number) + payload
    raw = body + struct.pack("<I", zlib.crc32(body))
    return raw, cobs(raw) + b"\x00"


def show(name, pair):
    raw, wire = pair
    print(f"# {name}")
    print("raw  " + " ".join(f"{b:02x}" for b in raw))
    print("wire " + " ".join(f"{b:02x}" for b in wire))
    print()


UP, DOWN = 0x84, 0x83
stream_start = bytes([0x00, 0x04, 0x02, 0x02, 0x08, 0x01, 0x01, 0x01])
show("up: start session", frame(UP, 4, SESSION, 0, 0, struct.pack("<I", 0)))
show("up: carry 0", frame(UP, 0, SESSION, BOOT, 0, stream_start))
show("up: resend 7..10", frame(UP, 1, SESSION, BOOT, 0, struct.pack("<IH", 7, 3)))
show("up: resend end", frame(UP, 2, SESSION, BOOT, 0))
show("up: query 77 ray", frame(UP, 3, SESSION, BOOT, 77,
                               struct.pack("<B6f", 1, 1.5, -2.0, 0.25, 0.0, 0.6, -0.8)))

show("down: booted", frame(DOWN, 5, 0, BOOT, 0, struct.pack("<BBIIB", 0, 0, 700, 150, 1)))
show("down: started", frame(DOWN, 5, SESSION, BOOT, 1, struct.pack("<BBIIB", 1, 0, 700, 150, 1)))
entity = struct.pack("<IB3f3f4f", 0, 2, 1.5, -2.0, 0.25, 4.0, 0.0, 100.0, 0.0, 0.0, 0.0, 1.0)
show("down: entity", frame(DOWN, 0, SESSION, BOOT, 2, entity))
show("down: progress", frame(DOWN, 2, SESSION, BOOT, 3, struct.pack("<4I", 3124, 2, 13, 1)))
end = (struct.pack("<IB3f3f", 1, 1, 0, 0, 0, 0.5, 0.0, -1.0)
       + struct.pack("<3d", 512000.25, -3.5, 1024.0)
       + struct.pack("<4I", 86, 0x12345678, 256, 2))
show("down: end", frame(DOWN, 1, SESSION, BOOT, 4, end))
timing = struct.pack("<6Q", 2_000_000, 150_000, 90_000, 1_000, 1_000, 5_400)
show("down: timing", frame(DOWN, 3, SESSION, BOOT, 5, timing))
answer = struct.pack("<IBIdI", 77, 1, 3, 2.5, 41_000)
show("down: answer", frame(DOWN, 4, SESSION, BOOT, 6, answer))
