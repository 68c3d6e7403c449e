#!/usr/bin/env python3
"""Writes the seed corpus of the frame-parser fuzzer (corpus/*.bin). Independent of the C++ encoder:
frames are built here from docs/icd.md, so the corpus also checks the codec against the document."""
import os
import random
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def crc16_ccitt_false(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


assert crc16_ccitt_false(b"123456789") == 0x29B1


def sample(seq, t_us, a, b, status=0x07):
    body = struct.pack("<BHIhhB", 0x01, seq, t_us, a, b, status)
    return b"\xA5\x5A" + body + struct.pack("<H", crc16_ccitt_false(body))


def reply(text):
    raw = text.encode("ascii")
    body = bytes([0x02, len(raw)]) + raw
    return b"\xA5\x5A" + body + struct.pack("<H", crc16_ccitt_false(body))


def main():
    rng = random.Random(20240601)
    out = os.path.join(HERE, "corpus")
    os.makedirs(out, exist_ok=True)
    seeds = {
        "one_sample": sample(1, 123456, -1200, 3400),
        "one_reply": reply("FPSS,SN=0042,FW=1.3.0"),
        "empty_and_longest_reply": reply("") + reply("x" * 255),
        "merged": b"".join(sample(i, i * 5000, i, -i) for i in range(5)) + reply("OK") + sample(5, 25000, 0, 0),
        "garbage_between": bytes([0x00, 0xA5, 0x13]) + sample(7, 0, 1, 1) + bytes([0xA5, 0x5A, 0x09]) + reply("TEMP 21.5"),
        "bad_crc": sample(1, 0, 5, 5)[:-1] + b"\x00" + sample(2, 5000, 5, 5),
        "false_sync_long_reply": b"\xA5\x5A\x02\xFF" + b"".join(sample(i, i, 0, 0) for i in range(20)),
        "truncated": sample(3, 15000, 9, 9)[:9] + sample(4, 20000, 9, 9) + sample(5, 25000, 9, 9)[:5],
        "seq_and_clock_wrap": b"".join(sample(s & 0xFFFF, (0xFFFFF000 + k * 5000) & 0xFFFFFFFF, 0, 0)
                                       for k, s in enumerate([65534, 65535, 0, 1, 4])),
        "noise": bytes(rng.choice([0xA5, 0x5A, 0x01, 0x02, rng.randrange(256)]) for _ in range(300)),
    }
    # What a correct parser finds in each seed fed whole: samples, replies, CRC errors.
    expected = {
        "one_sample": (1, 0, 0), "one_reply": (0, 1, 0), "empty_and_longest_reply": (0, 2, 0),
        "merged": (6, 1, 0), "garbage_between": (1, 1, 0), "bad_crc": (1, 0, 1),
        "false_sync_long_reply": (20, 0, 1), "truncated": (1, 0, 1), "seq_and_clock_wrap": (5, 0, 0),
    }
    for name, data in seeds.items():
        with open(os.path.join(out, name + ".bin"), "wb") as f:
            f.write(data)
    with open(os.path.join(HERE, "expected.txt"), "w") as f:
        f.write("# seed samples replies crc_errors (written by make_corpus.py)\n")
        for name, (s, r, c) in expected.items():
            f.write(f"{name}.bin {s} {r} {c}\n")


if __name__ == "__main__":
    main()
