#!/usr/bin/python3
"""The stand's two devices written from docs/icd.md alone: an independent check of the contract.

A gimbal (Modbus TCP server, docs/icd.md section 1) and an FPSS sensor (binary frames and ASCII
commands on a pseudo-terminal, section 2), coupled through one simple bench:

- the gimbal moves each axis at the profile speed (holding 8-9) straight toward the target a
  command took, and reports its encoders, rates, status and its clock;
- the sensor sees the Sun at the gimbal's angles (its alpha at gimbal pitch and beta at gimbal
  yaw, or as --mount says) and reports counts through the paper's transfer function (eq. 1,
  coefficients from a published set) inverted, plus Gaussian count noise rounded to whole counts,
  and, when asked, glitch frames: a valid frame with one axis's count off by +-N counts;
- both report one bench clock (microseconds), which runs --speed times the wall clock.

Nothing here comes from fixtures/ or drivers/: only the standard library and numpy.

    icd_devices.py [--port 0] [--speed 20] [--seed N] [--serial FPSS1-IND]
                   [--sensor-noise 0.3] [--sensor-glitch-rate 0.004 --sensor-glitch-counts 400]

prints one JSON line when both devices serve ({"modbus_port", "gimbal_endpoint", "sensor_pty",
"sensor_endpoint", ...}) and runs until SIGTERM or SIGINT (or stdin closes, with --stop-on-stdin-eof).

Several sensor units on the one gimbal (docs/icd.md section 2, "Several sensors on one stand"):

    icd_devices.py --sensor FPSS1-IND:a-6-fpss1 --sensor FPSS2-IND:a-6-fpss2:alpha=-yaw,beta=pitch
                   [--sensor-silent 2:80] [--sensor-unplug 2:80]

serves one pty per unit, each with its own truth, mount, serial, seq and noise stream (unit 1
seeded by --seed, unit K by "SEED/K"); nothing couples them but the gimbal they all see. The ready
line keeps the keys above for the first unit and adds "sensors": [{"serial", "sensor_pty",
"sensor_endpoint", "coefficients", "mount"}, ...] in --sensor order. --sensor-silent K:T makes unit
K say nothing more (no frames, no replies, its line open) from T bench seconds after its first
START; --sensor-unplug K:T closes its pty then. Noise and glitch options apply to every unit.
"""

import argparse
import json
import math
import os
import random
import select
import signal
import socket
import socketserver
import struct
import sys
import termios
import threading
import time
import tty

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.dirname(os.path.dirname(HERE))
RAD_PER_ARCSEC = math.pi / (180 * 3600)
MAS_PER_DEG = 3_600_000
HARD_LIMIT_MAS = 7_200_000  # +-2 deg


# ---------------------------------------------------------------------------------------------
# The bench clock


class BenchClock:
    """Microseconds of bench time, `speed` times the host's monotonic clock."""

    def __init__(self, speed, start_us=0):
        self.speed = speed
        self.start_us = start_us
        self.t0 = time.monotonic()

    def now_us(self):
        return self.start_us + int((time.monotonic() - self.t0) * self.speed * 1e6)

    def wall_of(self, bench_us):
        return self.t0 + (bench_us - self.start_us) / (self.speed * 1e6)


# ---------------------------------------------------------------------------------------------
# The gimbal: a bench model and its register map


class Segment:
    """One motion from t0 (bench us): a move toward targets, a rate, or standing still."""

    def __init__(self, t0, p0, kind, targets=None, speed_mas_s=0.0, rates=(0.0, 0.0)):
        self.t0 = t0
        self.p0 = list(p0)
        self.kind = kind  # 'still' | 'move' | 'home' | 'rate'
        self.targets = list(targets) if targets is not None else list(p0)
        self.speed = float(speed_mas_s)
        self.rates = list(rates)
        self.arrive = t0
        if kind in ("move", "home"):
            longest = max(abs(self.targets[i] - self.p0[i]) for i in range(2))
            self.arrive = t0 + (longest / self.speed * 1e6 if longest > 0 else 0.0)

    def position(self, t):
        dt = max(0.0, (t - self.t0) / 1e6)
        out, rate = [], []
        for i in range(2):
            if self.kind in ("move", "home"):
                d = self.targets[i] - self.p0[i]
                travelled = self.speed * dt
                if travelled >= abs(d):
                    out.append(float(self.targets[i]))
                    rate.append(0.0)
                else:
                    out.append(self.p0[i] + math.copysign(travelled, d))
                    rate.append(math.copysign(self.speed, d))
            elif self.kind == "rate":
                p = self.p0[i] + self.rates[i] * dt
                if abs(p) >= HARD_LIMIT_MAS:
                    out.append(math.copysign(HARD_LIMIT_MAS, p))
                    rate.append(0.0)
                else:
                    out.append(p)
                    rate.append(float(self.rates[i]))
            else:
                out.append(float(self.p0[i]))
                rate.append(0.0)
        return out, rate

    def moving(self, t):
        if self.kind in ("move", "home"):
            return t < self.arrive
        if self.kind == "rate":
            return any(r != 0 for r in self.position(t)[1])
        return False


class GimbalModel:
    """The gimbal's physics and registers; every call takes the bench time it happens at."""

    def __init__(self, clock, start=(360_000, -180_000)):
        self.clock = clock
        self.lock = threading.RLock()
        t = clock.now_us()
        self.segments = [Segment(t, start, "still")]
        self.completed = 0  # arrivals of segments before the current one
        self.homed = False
        self.fault = 0
        self.limit_bits = 0
        self.holding = [0] * 17
        self.set32(8, 1_800_000)  # profile speed at power-up: 1800 arcsec/s
        self.holding[10] = 1000  # in-position window at power-up: 1 arcsec
        self.pending = None  # (targets, move_at_us)
        self.rest_seen_us = None  # first reading at rest since the last move began
        self.moves_made = 0
        self.last_request_us = t
        self.log_refusals = False  # --log-refusals: say on stderr why a command 6 was refused

    # -- registers --
    def get32(self, addr, signed=True):
        v = (self.holding[addr] << 16) | self.holding[addr + 1]
        if signed and v >= 0x80000000:
            v -= 1 << 32
        return v

    def set32(self, addr, value):
        value &= 0xFFFFFFFF
        self.holding[addr] = value >> 16
        self.holding[addr + 1] = value & 0xFFFF

    def get64(self, addr):
        v = 0
        for i in range(4):
            v = (v << 16) | self.holding[addr + i]
        return v

    # -- physics --
    def segment_at(self, t):
        for seg in reversed(self.segments):
            if seg.t0 <= t:
                return seg
        return self.segments[0]

    def position_at(self, t):
        """Encoder angles (mas) at bench time t, for the sensor; t may lie slightly in the past."""
        with self.lock:
            self._update(t)
            return self.segment_at(t).position(t)[0]

    def _start(self, seg):
        cur = self.segments[-1]
        if cur.kind in ("move", "home") and cur.arrive <= seg.t0:
            self.completed += 1
        self.segments.append(seg)
        del self.segments[:-64]
        if seg.kind in ("move", "home"):
            self.moves_made += 1
            self.rest_seen_us = None

    def _update(self, t):
        """Apply what happens by bench time t: the watchdog, a pending move's start."""
        cur = self.segments[-1]
        wd = self.holding[12]
        # In motion when the watchdog ran out (a move that began after that: at its start), even
        # if it would have arrived by now (docs/icd.md, the watchdog).
        at = max(cur.t0, self.last_request_us + wd * 1000)
        if wd and t > at and cur.moving(at):
            self._start(Segment(at, cur.position(at)[0], "still"))
            self.fault = 4
            self.pending = None
            cur = self.segments[-1]
        if cur.kind == "rate":
            pos, _ = cur.position(t)
            self.limit_bits = (1 if abs(pos[0]) >= HARD_LIMIT_MAS else 0) | (
                2 if abs(pos[1]) >= HARD_LIMIT_MAS else 0)
        if self.pending is not None:
            targets, move_at = self.pending
            if t < move_at:
                return
            if self.moves_made == 0 and not cur.moving(move_at):
                start = move_at
            elif (not cur.moving(t) and cur.kind != "rate" and self.rest_seen_us is not None
                  and self.rest_seen_us <= t):
                start = max(move_at, self.rest_seen_us)
            else:
                return
            self.pending = None
            p0 = cur.position(start)[0]
            self._start(Segment(start, p0, "move", targets, self._speed()))

    def _speed(self):
        return max(1, self.get32(8, signed=False))

    def input_registers(self, t):
        with self.lock:
            self._update(t)
            seg = self.segments[-1]
            pos, rate = seg.position(t)
            moving = seg.moving(t)
            window = self.holding[10]
            in_pos = (not moving and seg.kind in ("move", "home", "still")
                      and all(abs(pos[i] - seg.targets[i]) <= window for i in range(2)))
            completed = self.completed + (1 if seg.kind in ("move", "home") and not moving else 0)
            status = ((1 if self.homed or (seg.kind == "home" and not moving) else 0)
                      | (2 if moving else 0) | (4 if in_pos else 0)
                      | (8 if self.fault else 0) | (self.limit_bits << 4)
                      | (64 if seg.kind == "rate" else 0)
                      | (128 if self.pending is not None else 0))
            if seg.kind == "home" and not moving:
                self.homed = True
            regs = []
            for v in (round(pos[0]), round(pos[1]), round(rate[0]), round(rate[1])):
                v &= 0xFFFFFFFF
                regs += [v >> 16, v & 0xFFFF]
            regs += [status, self.fault]
            regs += [(t >> s) & 0xFFFF for s in (48, 32, 16, 0)]
            regs.append(completed & 0xFFFF)
            # A reading at rest lets a queued move go (docs/icd.md, the scheduled move).
            if not moving and seg.kind != "rate" and self.rest_seen_us is None:
                self.rest_seen_us = t
                self._update(t)
            return regs

    def command(self, t, cmd):
        """Command `cmd` written to holding 11 at bench time t; returns a Modbus exception or 0."""
        with self.lock:
            self._update(t)
            cur = self.segments[-1]
            pos = cur.position(t)[0]
            targets = [self.get32(0), self.get32(2)]
            if cmd in (1, 6) and any(abs(v) > HARD_LIMIT_MAS for v in targets):
                return 3
            if cmd == 1:
                if self.fault:
                    return 3
                self.pending = None
                self._start(Segment(t, pos, "move", targets, self._speed()))
            elif cmd == 2:
                self.pending = None
                self._start(Segment(t, pos, "still"))
            elif cmd == 3:
                if self.fault:
                    return 3
                self.pending = None
                self.set32(0, 0)
                self.set32(2, 0)
                self._start(Segment(t, pos, "home", (0, 0), self._speed()))
            elif cmd == 4:
                self.pending = None
                self.fault = 0
                self.limit_bits = 0
            elif cmd == 5:
                if self.fault:
                    return 3
                rates = [self.get32(4), self.get32(6)]
                if any(abs(r) > self._speed() for r in rates):
                    return 3
                self.pending = None
                self._start(Segment(t, pos, "rate", rates=rates))
            elif cmd == 6:
                move_at = self.get64(13)
                if move_at <= t or self.fault or cur.kind == "rate":
                    if self.log_refusals:
                        sys.stderr.write(
                            "icd_devices: command 6 refused at bench %.6f s: move_at %.6f s (%s), "
                            "fault %d, %s\n" % (t / 1e6, move_at / 1e6,
                                                "%.1f ms in the past" % ((t - move_at) / 1e3)
                                                if move_at <= t else "in the future",
                                                self.fault, cur.kind))
                    return 3
                self.pending = (targets, move_at)
                self._update(t)
            else:
                return 3
            return 0

    def request(self, t):
        with self.lock:
            self._update(t)
            self.last_request_us = t


class ModbusError(Exception):
    def __init__(self, code):
        super().__init__(code)
        self.code = code


class GimbalServer(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, port, model, unit_id=1):
        self.model = model
        self.unit_id = unit_id
        super().__init__(("127.0.0.1", port), GimbalHandler)

    def pdu(self, pdu):
        """One request PDU -> the reply PDU (docs/icd.md section 1)."""
        model = self.model
        fc = pdu[0]
        t = model.clock.now_us()
        model.request(t)
        try:
            if fc in (3, 4):
                if len(pdu) != 5:
                    raise ModbusError(3)
                addr, count = struct.unpack(">HH", pdu[1:5])
                if not 1 <= count <= 125:
                    raise ModbusError(3)
                size = 15 if fc == 4 else 17
                if addr + count > size:
                    raise ModbusError(2)
                if fc == 4:
                    regs = model.input_registers(t)
                else:
                    with model.lock:
                        regs = list(model.holding)
                regs = regs[addr:addr + count]
                return bytes([fc, 2 * count]) + struct.pack(">%dH" % count, *regs)
            if fc == 6:
                if len(pdu) != 5:
                    raise ModbusError(3)
                addr, value = struct.unpack(">HH", pdu[1:5])
                self.write(t, addr, [value])
                return pdu
            if fc == 16:
                addr, count, nbytes = struct.unpack(">HHB", pdu[1:6])
                if not 1 <= count <= 123 or nbytes != 2 * count or len(pdu) != 6 + nbytes:
                    raise ModbusError(3)
                values = list(struct.unpack(">%dH" % count, pdu[6:6 + nbytes]))
                self.write(t, addr, values)
                return pdu[:5]
            raise ModbusError(1)
        except ModbusError as e:
            return bytes([fc | 0x80, e.code])

    def write(self, t, addr, values):
        model = self.model
        if addr + len(values) > 17:
            raise ModbusError(2)
        with model.lock:
            new = list(model.holding)
            new[addr:addr + len(values)] = values
            for a in (0, 2):  # targets beyond the hard limits: exception 03
                if addr <= a + 1 and a < addr + len(values):
                    v = (new[a] << 16) | new[a + 1]
                    v = v - (1 << 32) if v >= 0x80000000 else v
                    if abs(v) > HARD_LIMIT_MAS:
                        raise ModbusError(3)
            if addr <= 11 < addr + len(values):
                cmd = new[11]
                if cmd not in (1, 2, 3, 4, 5, 6):
                    raise ModbusError(3)
                keep = model.holding
                model.holding = new
                code = model.command(t, cmd)
                if code:
                    model.holding = keep
                    raise ModbusError(code)
            else:
                model.holding = new


class GimbalHandler(socketserver.BaseRequestHandler):
    def handle(self):
        sock = self.request
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        while True:
            head = self.read(7)
            if head is None:
                return
            tid, proto, length, unit = struct.unpack(">HHHB", head)
            if length < 2 or length > 254:
                return
            pdu = self.read(length - 1)
            if pdu is None or proto != 0:
                return
            if unit != self.server.unit_id:
                continue  # another unit's request: no answer
            reply = self.server.pdu(pdu)
            sock.sendall(struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply)

    def read(self, n):
        data = b""
        while len(data) < n:
            try:
                chunk = self.request.recv(n - len(data))
            except OSError:
                return None
            if not chunk:
                return None
            data += chunk
        return data


# ---------------------------------------------------------------------------------------------
# The sensor: transfer function, frames, commands


def crc16_ccitt_false(data):
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def frame(body):
    """Sync, body (type onwards), CRC of the body little-endian."""
    return b"\xA5\x5A" + body + struct.pack("<H", crc16_ccitt_false(body))


def sample_frame(seq, time_us, alpha, beta, status):
    return frame(struct.pack("<BHIhhB", 1, seq & 0xFFFF, time_us & 0xFFFFFFFF, alpha, beta, status))


def reply_frame(text):
    data = text.encode("ascii")[:255]
    return frame(bytes([2, len(data)]) + data)


class TransferFunction:
    """Paper eq. 1, angle(N) = C1 + C2 N + C3 sin(C4 N + C5) + C6 sin(C7 N + C8) (radians),
    tabulated at every i16 count and inverted by interpolation (it is monotonic there)."""

    def __init__(self, c):
        n = np.arange(-32768, 32768, dtype=float)
        a = c[0] + c[1] * n + c[2] * np.sin(c[3] * n + c[4]) + c[5] * np.sin(c[6] * n + c[7])
        if c[1] < 0:
            n, a = n[::-1], a[::-1]
        if not np.all(np.diff(a) > 0):
            raise ValueError("transfer function not monotonic over the i16 counts")
        self.n, self.a = n, a

    def counts(self, angle_rad):
        """Real-valued counts at which the sensor sees angle_rad, or None outside its range."""
        if not self.a[0] <= angle_rad <= self.a[-1]:
            return None
        return float(np.interp(angle_rad, self.a, self.n))


class Sensor:
    """One sensor unit on a pty of its own. `serial`, `coefficients`, `mount` and `seed` default to
    the single sensor's options (--serial, --coefficients, --mount, --seed); several units each get
    their own (--sensor), and all see the one gimbal (docs/icd.md section 2, several sensors)."""

    def __init__(self, clock, gimbal, args, serial=None, coefficients=None, mount=None, seed=None,
                 silent_after_s=None, unplug_after_s=None):
        self.clock = clock
        self.gimbal = gimbal
        self.serial = args.serial if serial is None else serial
        self.rate_hz = 50
        self.streaming = False
        self.rng = random.Random(args.seed if seed is None else seed)
        self.noise = args.sensor_noise
        self.glitch_rate = args.sensor_glitch_rate
        self.glitch_counts = args.sensor_glitch_counts
        self.glitch_pattern = args.sensor_glitch_pattern
        self.block_left = 0
        self.glitch_at = 0
        self.half_fov_rad = args.sensor_half_fov_deg * 3600 * RAD_PER_ARCSEC
        self.coefficients = args.coefficients if coefficients is None else coefficients
        with open(self.coefficients) as f:
            coeffs = json.load(f)
        self.tf = {"alpha": TransferFunction(coeffs["alpha"]),
                   "beta": TransferFunction(coeffs["beta"])}
        # --mount: which gimbal axis (and sign) each sensor axis sees
        self.mount_text = args.mount if mount is None else mount
        self.mount = {}
        for part in self.mount_text.split(","):
            axis, src = part.split(":")
            sign = -1.0 if src.startswith("-") else 1.0
            self.mount[axis] = (src.lstrip("+-"), sign)
        if set(self.mount) != {"alpha", "beta"} or any(
                src not in ("pitch", "yaw") for src, _ in self.mount.values()):
            raise ValueError("mount %r: want alpha:[+-]pitch|yaw,beta:[+-]pitch|yaw" % self.mount_text)
        # --sensor-silent / --sensor-unplug: this many bench seconds after the first START the unit
        # says nothing more (its line stays open, input is read and dropped), or its line goes away
        # (pty closed). The bench times are set at that START.
        self.silent_after_s = silent_after_s
        self.unplug_after_s = unplug_after_s
        self.silent_after_us = None
        self.unplug_after_us = None
        self.silenced = False
        self.unplugged = False
        self.seq = self.rng.randrange(65536)
        self.next_us = None
        self.frames_sent = 0
        self.glitches = 0
        self.lock = threading.Lock()
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        attrs = termios.tcgetattr(self.slave)
        attrs[4] = attrs[5] = termios.B115200
        termios.tcsetattr(self.slave, termios.TCSANOW, attrs)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.out = bytearray()
        self.inbuf = bytearray()

    def command(self, line):
        words = line.strip().split()
        if not words:
            return None
        cmd = words[0].upper()
        if cmd == "ID?" and len(words) == 1:
            return "FPSS,SN=%s,FW=ind-1.0" % self.serial
        if cmd == "RATE" and len(words) == 2:
            try:
                hz = int(words[1])
            except ValueError:
                return "ERR bad rate"
            if not 1 <= hz <= 200:
                return "ERR rate out of range 1..200"
            with self.lock:  # while streaming too: the next frame one new period on
                if self.streaming:
                    self.next_us += 1e6 / hz - 1e6 / self.rate_hz
                self.rate_hz = hz
            return "OK"
        if cmd == "START" and len(words) == 1:
            with self.lock:
                if not self.streaming:
                    self.streaming = True
                    self.next_us = self.clock.now_us()
                    if self.silent_after_s is not None and self.silent_after_us is None:
                        self.silent_after_us = self.next_us + int(self.silent_after_s * 1e6)
                    if self.unplug_after_s is not None and self.unplug_after_us is None:
                        self.unplug_after_us = self.next_us + int(self.unplug_after_s * 1e6)
            return "OK"
        if cmd == "STOP" and len(words) == 1:
            with self.lock:
                self.streaming = False
            return "OK"
        if cmd == "TEMP?" and len(words) == 1:
            return "TEMP 21.5"
        return "ERR unknown command"

    def sample(self, t_us):
        pos = self.gimbal.position_at(t_us)
        gimbal = {"pitch": pos[0], "yaw": pos[1]}
        angles = {}
        for axis in ("alpha", "beta"):
            src, sign = self.mount[axis]
            angles[axis] = sign * gimbal[src] / 1000.0 * RAD_PER_ARCSEC
        if any(abs(a) > self.half_fov_rad for a in angles.values()):
            return sample_frame(self.seq, t_us, 0, 0, 0)  # no Sun in the field
        counts, status = {}, 1  # sun present
        for axis, bit in (("alpha", 2), ("beta", 4)):
            n = self.tf[axis].counts(angles[axis])
            if n is None:
                counts[axis] = 0
                continue
            c = int(round(n + self.rng.gauss(0.0, self.noise)))
            counts[axis] = max(-32768, min(32767, c))
            status |= bit
        if status & 1 and self.glitch_due():
            axis = self.rng.choice(("alpha", "beta")) if self.glitch_pattern == "bernoulli" else (
                ("alpha", "beta")[self.glitches % 2])
            off = self.glitch_counts * self.rng.choice((-1, 1))
            counts[axis] = max(-32768, min(32767, counts[axis] + off))
            self.glitches += 1
        return sample_frame(self.seq, t_us, counts["alpha"], counts["beta"], status)

    def glitch_due(self):
        """Whether this frame is a glitch. `bernoulli`: each frame with probability `rate`;
        `stratified` (default): one glitch at a seeded place in every block of 1/rate frames, the
        axes taken in turn, so a run's count of glitch frames hardly depends on which frames the
        host happened to record (a test that must fail on them is then not left to chance)."""
        if self.glitch_rate <= 0:
            return False
        if self.glitch_pattern == "bernoulli":
            return self.rng.random() < self.glitch_rate
        block = max(1, round(1 / self.glitch_rate))
        if self.block_left == 0:
            self.block_left = block
            self.glitch_at = self.rng.randrange(block)
        self.block_left -= 1
        return self.block_left == self.glitch_at

    def due_frames(self):
        with self.lock:
            if not self.streaming:
                return
            now = self.clock.now_us()
            period = 1e6 / self.rate_hz
            while self.next_us <= now:
                self.out += self.sample(int(self.next_us))
                self.seq = (self.seq + 1) & 0xFFFF
                self.frames_sent += 1
                self.next_us += period

    def go_quiet(self):
        """--sensor-silent: streaming state and seq go on (a cable cut, not a sensor stopped), but
        nothing reaches the line: no frames, no replies."""
        with self.lock:
            now = self.clock.now_us()
            if self.streaming and self.next_us <= now:
                period = 1e6 / self.rate_hz
                n = int((now - self.next_us) // period) + 1
                self.seq = (self.seq + n) & 0xFFFF
                self.next_us += n * period
            self.out.clear()

    def unplug(self):
        """--sensor-unplug: the line goes away: both ends of the pty closed (its path vanishes)."""
        self.unplugged = True
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def run(self, stop):
        while not stop.is_set():
            timed = self.unplug_after_us is not None or self.silent_after_us is not None
            now_us = self.clock.now_us() if timed else 0
            if self.unplug_after_us is not None and now_us >= self.unplug_after_us:
                self.unplug()
                sys.stderr.write("icd_devices: sensor %s unplugged at bench %.3f s\n"
                                 % (self.serial, now_us / 1e6))
                return
            if self.silent_after_us is not None and now_us >= self.silent_after_us:
                if not self.silenced:
                    self.silenced = True
                    sys.stderr.write("icd_devices: sensor %s silent from bench %.3f s\n"
                                     % (self.serial, now_us / 1e6))
                r, _, _ = select.select([self.master], [], [], 0.05)
                if r:
                    try:
                        os.read(self.master, 4096)
                    except OSError:
                        pass
                self.inbuf.clear()
                self.go_quiet()
                continue
            with self.lock:
                wake = (self.clock.wall_of(self.next_us) if self.streaming else time.monotonic() + 0.05)
            timeout = max(0.0, min(0.05, wake - time.monotonic()))
            want_write = [self.master] if self.out else []
            r, w, _ = select.select([self.master], want_write, [], timeout)
            if r:
                try:
                    data = os.read(self.master, 4096)
                except (BlockingIOError, InterruptedError):
                    data = b""
                except OSError:
                    data = b""
                self.inbuf += data
                while b"\n" in self.inbuf:
                    line, _, rest = bytes(self.inbuf).partition(b"\n")
                    self.inbuf = bytearray(rest)
                    reply = self.command(line.decode("ascii", "replace"))
                    if reply is not None:
                        self.out += reply_frame(reply)
            self.due_frames()
            if self.out:
                try:
                    n = os.write(self.master, bytes(self.out))
                    del self.out[:n]
                except (BlockingIOError, InterruptedError):
                    pass
                except OSError:
                    self.out.clear()
                # Back-pressure: nobody reading; keep at most a second of frames.
                if len(self.out) > 16 * 200 * 2:
                    del self.out[:len(self.out) - 16 * 200]


# ---------------------------------------------------------------------------------------------


def published(name):
    """A coefficient file: a path, or the name of a published set (`a-6-fpss2`: calib/data)."""
    if os.path.sep in name or name.endswith(".json"):
        return name
    return os.path.join(SOURCE, "calib/data/published", name + ".json")


def parse_sensor(text):
    """--sensor SERIAL:COEFFICIENTS[:MOUNT] -> (serial, coefficients file, mount or None).

    SERIAL holds no ':' (nor ',', docs/icd.md: ID?); COEFFICIENTS is a file or a published set's
    name (a-6-fpss1); MOUNT is written with '=' where --mount has ':' (alpha=-yaw,beta=pitch), so a
    last field with '=' is the mount and everything between is the file."""
    serial, sep, rest = text.partition(":")
    if not sep or not serial or "," in serial or not rest:
        raise argparse.ArgumentTypeError(
            "--sensor %r: want SERIAL:COEFFICIENTS[:MOUNT], e.g. FPSS2-IND:a-6-fpss2:alpha=-yaw,beta=pitch"
            % text)
    mount = None
    head, sep, last = rest.rpartition(":")
    if sep and "=" in last:
        rest, mount = head, last.replace("=", ":")
    return serial, published(rest), mount


def parse_unit_time(text):
    """K:T -> (unit K, 1-based, bench seconds T after the devices start)."""
    k, sep, t = text.partition(":")
    try:
        if not sep or int(k) < 1 or float(t) < 0:
            raise ValueError
        return int(k), float(t)
    except ValueError:
        raise argparse.ArgumentTypeError("%r: want K:T (unit K from 1, T bench seconds)" % text)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, default=0, help="Modbus TCP port (0: any free one)")
    p.add_argument("--speed", type=float, default=20.0, help="bench seconds per wall second")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--serial", default="FPSS1-IND")
    p.add_argument("--coefficients",
                   default=os.path.join(SOURCE, "calib/data/published/a-6-fpss1.json"))
    p.add_argument("--mount", default="alpha:pitch,beta:yaw",
                   help="which gimbal axis each sensor axis sees, e.g. alpha:-yaw,beta:pitch")
    p.add_argument("--sensor", action="append", type=parse_sensor, default=[],
                   metavar="SERIAL:COEFFICIENTS[:MOUNT]",
                   help="several units on the one gimbal, one pty each, in this order (repeatable; "
                        "replaces --serial/--coefficients/--mount). COEFFICIENTS: a file or a "
                        "published set's name (a-6-fpss2); MOUNT as --mount with '=' for ':' "
                        "(alpha=-yaw,beta=pitch; default alpha=pitch,beta=yaw). Unit 1's noise "
                        "stream is --seed's, as the single sensor's; unit K's is seeded by "
                        "'SEED/K', independent of the others")
    p.add_argument("--sensor-silent", action="append", type=parse_unit_time, default=[],
                   metavar="K:T", help="unit K says nothing more (no frames, no replies; its line "
                                       "stays open) from T bench seconds after its first START")
    p.add_argument("--sensor-unplug", action="append", type=parse_unit_time, default=[],
                   metavar="K:T", help="unit K's pty is closed (its line vanishes) T bench seconds "
                                       "after its first START")
    p.add_argument("--sensor-noise", type=float, default=0.3, help="count noise, 1 sigma")
    p.add_argument("--sensor-half-fov-deg", type=float, default=0.95)
    p.add_argument("--sensor-glitch-rate", type=float, default=0.0)
    p.add_argument("--sensor-glitch-counts", type=int, default=400)
    p.add_argument("--sensor-glitch-pattern", choices=("stratified", "bernoulli"),
                   default="stratified")
    p.add_argument("--clock-start-us", type=int, default=0,
                   help="the bench clock's reading at start (near 2**32 puts a sensor wrap early)")
    p.add_argument("--sensor-link", help="also name the (first) sensor's pty by this symbolic link")
    p.add_argument("--log-refusals", action="store_true",
                   help="say on stderr why the gimbal refused a scheduled move (command 6)")
    p.add_argument("--stop-on-stdin-eof", action="store_true",
                   help="also stop when stdin closes (a parent that dies takes the devices along)")
    args = p.parse_args(argv)
    several = bool(args.sensor)
    n_units = len(args.sensor) if several else 1
    serials = [spec[0] for spec in args.sensor]
    if len(set(serials)) != len(serials):
        p.error("--sensor: two units with one serial")
    for opt, given in (("--sensor-silent", args.sensor_silent),
                       ("--sensor-unplug", args.sensor_unplug)):
        for k, _ in given:
            if k > n_units:
                p.error("%s: unit %d of %d" % (opt, k, n_units))

    clock = BenchClock(args.speed, args.clock_start_us)
    gimbal = GimbalModel(clock)
    gimbal.log_refusals = args.log_refusals
    server = GimbalServer(args.port, gimbal)

    def after(given, k):
        times = [t for unit, t in given if unit == k]
        return min(times) if times else None

    sensors = []
    for k in range(1, n_units + 1):
        timing = {"silent_after_s": after(args.sensor_silent, k),
                  "unplug_after_s": after(args.sensor_unplug, k)}
        if not several:
            sensors.append(Sensor(clock, gimbal, args, **timing))
            continue
        serial, coefficients, mount = args.sensor[k - 1]
        try:
            sensors.append(Sensor(clock, gimbal, args, serial=serial, coefficients=coefficients,
                                  mount=mount or "alpha:pitch,beta:yaw",
                                  seed=args.seed if k == 1 else "%d/%d" % (args.seed, k), **timing))
        except (OSError, ValueError, KeyError) as e:
            p.error("--sensor %s: %s" % (serial, e))
    sensor = sensors[0]
    if args.sensor_link:
        if os.path.lexists(args.sensor_link):
            os.unlink(args.sensor_link)
        os.symlink(sensor.path, args.sensor_link)

    stop = threading.Event()
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05},
                     daemon=True).start()
    for unit in sensors:
        threading.Thread(target=unit.run, args=(stop,), daemon=True).start()

    def finish(*_):
        stop.set()

    signal.signal(signal.SIGTERM, finish)
    signal.signal(signal.SIGINT, finish)
    port = server.server_address[1]
    ready = {"modbus_port": port, "gimbal_endpoint": "modbus-tcp:127.0.0.1:%d" % port,
             "sensor_pty": sensor.path, "sensor_endpoint": "pty:" + sensor.path,
             "serial": sensor.serial, "speed": args.speed, "seed": args.seed}
    if several:  # every unit's line, in --sensor order (the first one's also as above)
        ready["sensors"] = [{"serial": u.serial, "sensor_pty": u.path,
                             "sensor_endpoint": "pty:" + u.path, "coefficients": u.coefficients,
                             "mount": u.mount_text} for u in sensors]
    print(json.dumps(ready), flush=True)

    def watch_stdin():
        try:
            while sys.stdin.buffer.read1(4096):
                pass
        except (OSError, ValueError):
            pass
        stop.set()

    if args.stop_on_stdin_eof:
        threading.Thread(target=watch_stdin, daemon=True).start()
    while not stop.wait(0.2):
        pass
    server.shutdown()
    server.server_close()
    for unit in sensors:
        sys.stderr.write("icd_devices: %s%d frames sent, %d glitch frames\n"
                         % (unit.serial + ": " if several else "", unit.frames_sent, unit.glitches))
    return 0


if __name__ == "__main__":
    sys.exit(main())
