"""icd_devices.py (the devices written from docs/icd.md alone) in a child process, for the tests.

Ready when its JSON line has come (a bounded wait); closed by closing its stdin
(--stop-on-stdin-eof), killed if it does not stop.
"""

import json
import os
import select
import subprocess
import sys
import time

DEVICES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "icd_devices.py")


class DevicesProcess:
    def __init__(self, speed, *args, timeout_s=20):
        self.proc = subprocess.Popen(
            [sys.executable, DEVICES, "--port", "0", "--speed", str(speed), "--stop-on-stdin-eof", *args],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        os.set_blocking(self.proc.stdout.fileno(), False)
        deadline = time.monotonic() + timeout_s
        line = ""
        while not line.endswith("\n"):
            if self.proc.poll() is not None:
                raise RuntimeError("icd_devices.py exited: " + self.proc.stderr.read())
            if time.monotonic() > deadline:
                self.close()
                raise RuntimeError("icd_devices.py not ready within %d s" % timeout_s)
            select.select([self.proc.stdout], [], [], 0.1)
            line += self.proc.stdout.readline() or ""
        self.info = json.loads(line)

    def close(self):
        """Stops it; returns what it wrote on stderr (its log)."""
        if self.proc.poll() is None:
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.stderr.read()
