"""icd_devices.py against docs/icd.md's own examples and rules, without the stand's binary."""

import os
import re
import select
import socket
import struct
import sys
import time
import tty

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import icd_devices as d  # noqa: E402
from test_icd_accept import Devices  # noqa: E402


def modbus_requester(dev):
    """A Modbus TCP client of the device as one function: a request PDU in, the response PDU out."""
    s = socket.create_connection(("127.0.0.1", dev.info["modbus_port"]), timeout=5)
    tid = [0]

    def req(pdu):
        tid[0] += 1
        s.sendall(struct.pack(">HHHB", tid[0], 0, len(pdu) + 1, 1) + pdu)
        head = s.recv(7, socket.MSG_WAITALL)
        return s.recv(struct.unpack(">HHHB", head)[2] - 1, socket.MSG_WAITALL)

    return req


def test_crc_check_value_and_the_example_sample():
    assert d.crc16_ccitt_false(b"123456789") == 0x29B1
    f = d.sample_frame(0x0102, 0x03040506, -2, 0x1234, 0x0F)
    assert f[:14] == bytes.fromhex("A55A01020106050403FEFF34120F")
    assert struct.unpack("<H", f[14:])[0] == d.crc16_ccitt_false(f[2:14])


def test_register_example_and_the_sensor_commands():
    dev = Devices("--seed", "2")
    try:
        req = modbus_requester(dev)

        regs = struct.pack(">ii", -1234567, 0)
        assert regs[:4] == bytes.fromhex("FFED2979")  # the ICD's example
        assert req(struct.pack(">BHHB", 16, 0, 4, 8) + regs)[0] == 16
        assert req(struct.pack(">BHH", 6, 11, 9)) == bytes([0x86, 3])  # unknown command
        assert req(struct.pack(">BHH", 4, 0, 16)) == bytes([0x84, 2])  # unmapped
        bad = struct.pack(">ii", 7_200_001, 0)
        assert req(struct.pack(">BHHB", 16, 0, 4, 8) + bad) == bytes([0x90, 3])  # beyond +-2 deg

        fd = os.open(dev.info["sensor_pty"], os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        os.set_blocking(fd, False)
        os.write(fd, b"ID?\nRATE 50\nSTART\nRATE 100\nTEMP?\nRATE 0\nSTOP\n")
        data, deadline = b"", time.monotonic() + 10
        replies = []
        while len(replies) < 7 and time.monotonic() < deadline:
            select.select([fd], [], [], 0.1)
            try:
                data += os.read(fd, 65536)
            except BlockingIOError:
                pass
            replies, i = [], 0
            while True:
                i = data.find(b"\xA5\x5A", i)
                if i < 0 or i + 4 > len(data):
                    break
                if data[i + 2] == 1:
                    i += 16
                    continue
                n = data[i + 3]
                body = data[i + 2:i + 4 + n]
                if len(data) < i + 6 + n:
                    break
                assert struct.unpack("<H", data[i + 4 + n:i + 6 + n])[0] == d.crc16_ccitt_false(body)
                replies.append(body[2:].decode())
                i += 6 + n
        os.close(fd)
        assert replies[0] == "FPSS,SN=FPSS1-IND,FW=ind-1.0"
        assert replies[1:4] == ["OK", "OK", "OK"]  # RATE while streaming is taken
        assert re.fullmatch(r"TEMP -?[0-9]+(\.[0-9]+)?", replies[4])  # the ICD's TEMP format
        assert replies[5].startswith("ERR ")
        assert replies[6] == "OK"
    finally:
        dev.close()


def test_power_on_values_and_a_refused_request_changing_nothing():
    dev = Devices("--seed", "3")
    try:
        req = modbus_requester(dev)

        def holding(addr, n):
            r = req(struct.pack(">BHH", 3, addr, n))
            assert r[0] == 3
            return struct.unpack(">%dH" % n, r[2:])

        # At power-on: a profile speed, a window (never written by the host), the watchdog off.
        h = holding(0, 13)
        assert (h[8] << 16 | h[9]) > 0 and h[10] > 0 and h[12] == 0
        # Faulted (its watchdog: 1 ms, a move, silence), a move refused takes nothing of its request.
        assert req(struct.pack(">BHH", 6, 12, 1)) == struct.pack(">BHH", 6, 12, 1)
        assert req(struct.pack(">BHHB", 16, 0, 4, 8) + struct.pack(">ii", 360_000, 0))[0] == 16
        assert req(struct.pack(">BHH", 6, 11, 1))[0] == 6
        time.sleep(0.2)
        r = req(struct.pack(">BHH", 4, 0, 15))
        assert struct.unpack(">15H", r[2:])[9] == 4  # fault 4, watchdog
        with_move = struct.pack(">ii", -5000, 6000) + struct.pack(">8H", *([0] * 4 + list(h[8:11]) + [1]))
        assert len(with_move) == 24  # holding 0..11: targets, rate commands, max rate, window, command 1
        assert req(struct.pack(">BHHB", 16, 0, 12, 24) + with_move) == bytes([0x90, 3])
        assert struct.unpack(">ii", struct.pack(">4H", *holding(0, 4))) == (360_000, 0)
    finally:
        dev.close()
