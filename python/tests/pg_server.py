"""A throw-away PostgreSQL 15 cluster for the tests (as tests/support/pg_server.h): initdb and pg_ctl in a
temporary folder, a unix socket there and a free loopback port; under root every server command runs as
the `postgres` user. Never skipped: a missing server is a failure."""
import os
import pwd
import shutil
import socket
import subprocess
import tempfile

PG_BIN = os.environ.get("FPSS_PG_BIN", "/usr/lib/postgresql/15/bin")


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PgServer:
    def __init__(self):
        root_user = os.geteuid() == 0
        self.root = tempfile.mkdtemp(prefix="fpss-pg-", dir="/tmp" if root_user else None)
        self.prefix = []
        if root_user:
            pw = pwd.getpwnam("postgres")
            os.chown(self.root, pw.pw_uid, pw.pw_gid)
            self.prefix = ["runuser", "-u", "postgres", "--"]
        self.data = os.path.join(self.root, "data")
        self._run("initdb", "-D", self.data, "-U", "fpss", "--auth=trust", "-E", "UTF8", "--no-sync", "--locale=C")
        self.port = _free_port()
        conf = (f"listen_addresses = '127.0.0.1'\nport = {self.port}\nunix_socket_directories = '{self.root}'\n"
                "fsync = off\nsynchronous_commit = off\nfull_page_writes = off\nshared_buffers = 16MB\n")
        with open(os.path.join(self.data, "postgresql.conf"), "a") as f:  # root may write the postgres user's file
            f.write("\n" + conf)
        self._run("pg_ctl", "-D", self.data, "-l", os.path.join(self.root, "server.log"), "-w", "-t", "60", "start")
        self.url = f"postgresql://fpss@127.0.0.1:{self.port}/fpss?sslmode=disable"
        self._run("createdb", "-h", self.root, "-p", str(self.port), "-U", "fpss", "fpss")

    def _run(self, program, *args):
        subprocess.run(self.prefix + [os.path.join(PG_BIN, program), *args], check=True, capture_output=True, text=True)

    def stop(self):
        try:
            self._run("pg_ctl", "-D", self.data, "-m", "immediate", "-w", "stop")
        finally:
            shutil.rmtree(self.root, ignore_errors=True)
