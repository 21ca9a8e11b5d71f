#!/usr/bin/env python3
"""PROTOCOL.md's examples, every frame type of both protocols, computed from the document alone
(struct, zlib.crc32 and a COBS written from its definition), independently of mema. Each example
is printed as PROTOCOL.md shows it (`raw` and `wire` lines) under a `#` line naming it.

`tests/tests/protocol_doc.rs` checks that PROTOCOL.md's examples are exactly these, in this order,
and that mema reads each one and emits it again to the byte; the core's unit tests
(`wire::frame::tests::protocol_example*`, `uplink::tests::protocol_examples`,
`downlink::tests::protocol_examples`) check the same bytes from the other side.

    python3 scripts/protocol_examples.py
"""
import math
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


def wire_frame(version, flags, sequence, count, exponent, kind, pose, payload):
    """A rangefinder frame: the 14-byte header (10 bytes in version 1), the payload, CRC-32."""
    if version == 1:
        body = struct.pack("<BBIHbB", version, flags, sequence, count, exponent, 0) + payload
    else:
        body = struct.pack("<BBIHbBI", version, flags, sequence, count, exponent, kind, pose) + payload
    raw = body + struct.pack("<I", zlib.crc32(body))
    return raw, cobs(raw) + b"\x00"


def show(name, pair):
    raw, wire = pair
    print(f"# {name}")
    print("raw  " + " ".join(f"{b:02x}" for b in raw))
    print("wire " + " ".join(f"{b:02x}" for b in wire))
    print()


# The rangefinder's wire (PROTOCOL.md, "Raw frame"), millimetres (exponent -3).
END, START = 1, 2
show("wire: version 1 points", wire_frame(1, END, 7, 2, -3, 0, 0,
                                          struct.pack("<6i", 1000, -2000, 500, 0, 0, -1)))
Q45 = round(math.sin(math.pi / 4) * 2**30)
show("wire: pose", wire_frame(2, START, 8, 0, -3, 1, 1,
                              struct.pack("<3i4i", 1000, -2000, 500, 0, 0, Q45, Q45)))
show("wire: points", wire_frame(2, END, 9, 2, -3, 0, 1,
                                struct.pack("<6i", 1000, 0, 0, 0, 0, -1)))
show("wire: wide pose", wire_frame(2, 0, 10, 0, -3, 2, 2,
                                   struct.pack("<3q4i", 4198000400, 612000900, 4762000200,
                                               0, 0, 0, 2**30)))

UP, DOWN = 0x84, 0x83
show("down: booted", frame(DOWN, 5, 0, BOOT, 0, struct.pack("<BBIIB", 0, 0, 700, 150, 1)))
show("down: started", frame(DOWN, 5, SESSION, BOOT, 1, struct.pack("<BBIIB", 1, 0, 700, 150, 1)))
entity = struct.pack("<IB3f3f4f", 0, 2, 1.5, -2.0, 0.25, 4.0, 0.0, 100.0, 0.0, 0.0, 0.0, 1.0)
show("down: entity", frame(DOWN, 0, SESSION, BOOT, 2, entity))
show("down: progress", frame(DOWN, 2, SESSION, BOOT, 3, struct.pack("<4I", 3124, 2, 13, 1)))
end = (struct.pack("<IB3f3f", 1, 1, 0, 0, 0, 0.5, 0.0, -1.0)
       + struct.pack("<3d", 512000.25, -3.5, 1024.0)
       + struct.pack("<4I", 86, 0x12345678, 256, 2))
show("down: end", frame(DOWN, 1, SESSION, BOOT, 4, end))
# busy, interrupt, longest tick, calibration ticks, calibration instructions, stack, cycles,
# ring overruns, line overruns: the wire's order.
timing = struct.pack("<7Q2I", 2_000_000, 150_000, 90_000, 1_000, 2_500, 5_400, 3_000_000, 0, 2)
show("down: timing", frame(DOWN, 3, SESSION, BOOT, 5, timing))
answer = struct.pack("<IBIdI", 77, 1, 3, 2.5, 41_000)
show("down: answer", frame(DOWN, 4, SESSION, BOOT, 6, answer))
show("down: retract", frame(DOWN, 6, SESSION, BOOT, 7, struct.pack("<I", 5)))

# Host to device, after the device's frames, as PROTOCOL.md orders them.
stream_start = bytes([0x00, 0x04, 0x02, 0x02, 0x08, 0x01, 0x01, 0x01])
show("up: start session", frame(UP, 4, SESSION, 0, 0, struct.pack("<I", 0)))
show("up: carry 0", frame(UP, 0, SESSION, BOOT, 0, stream_start))
show("up: resend 7..10", frame(UP, 1, SESSION, BOOT, 0, struct.pack("<IH", 7, 3)))
show("up: resend end", frame(UP, 2, SESSION, BOOT, 0))
show("up: query 77 ray", frame(UP, 3, SESSION, BOOT, 77,
                               struct.pack("<B6f", 1, 1.5, -2.0, 0.25, 0.0, 0.6, -0.8)))
