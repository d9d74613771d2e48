"""Helpers of the firmware_sim tests: start the emulator as a process, a plain pymavlink client,
the command line's engine in process with a kept link (:class:`Vehicle`)."""
from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink2

from firmware_sim.cli import build_engine, build_parser
from tests.helpers.repo import ROOT as REPO

GCS = 245      # MAVSDK's system id


class Emulator:
    """``python -m firmware_sim`` on a free loopback port; stopped with SIGTERM."""

    def __init__(self, *args: str, record: Path | None = None):
        cmd = [sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0", "--quiet", *args]
        if record is not None:
            cmd += ["--record", str(record)]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     cwd=REPO, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        line = self.proc.stdout.readline()
        if not line.startswith("firmware_sim listening on udpin:"):
            self.proc.kill()
            raise RuntimeError(f"no start line: {line!r} {self.proc.stderr.read()}")
        self.port = int(line.strip().rsplit(":", 1)[1])

    def stop(self, timeout_s: float = 10.0) -> int:
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        return self.proc.returncode

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


class Client:
    """A plain pymavlink codec over a UDP socket (what the daemon does)."""

    def __init__(self, port: int, system_id: int = 1, component_id: int = 191):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.connect(("127.0.0.1", port))
        self.mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.pending: list = []

    def send(self, msg) -> None:
        self.sock.send(msg.pack(self.mav) if not isinstance(msg, (bytes, bytearray)) else msg)

    def heartbeat(self) -> None:
        self.send(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))

    def target(self, controls, target_system: int = 1, group: int = 0) -> None:
        c = list(controls) + [0.0] * (8 - len(controls))
        self.send(mavlink2.MAVLink_set_actuator_control_target_message(0, group, target_system, 1, c))

    def command(self, command: int, *params: float, target_system: int = 1) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        self.send(mavlink2.MAVLink_command_long_message(target_system, 1, command, 0, *p))

    def recv(self, timeout_s: float = 2.0):
        """Next message (or None on timeout)."""
        if self.pending:
            return self.pending.pop(0)
        self.sock.settimeout(timeout_s)
        try:
            data = self.sock.recv(65535)
        except (socket.timeout, ConnectionRefusedError):
            return None
        msgs = self.mav.parse_buffer(data) or []
        if not msgs:
            return self.recv(timeout_s)
        self.pending.extend(msgs[1:])
        return msgs[0]

    def wait_for(self, mtype: str, pred=lambda m: True, timeout_s: float = 5.0, on_msg=None):
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            m = self.recv(max(0.01, end - time.monotonic()))
            if m is None:
                continue
            if on_msg is not None:
                on_msg(m)
            if m.get_type() == mtype and pred(m):
                return m
        raise AssertionError(f"no {mtype} within {timeout_s} s")

    def ack(self, command: int, timeout_s: float = 5.0, on_msg=None) -> int:
        return self.wait_for("COMMAND_ACK", lambda m: m.command == command, timeout_s, on_msg).result

    def lockstep(self, n: int, controls, texts=None):
        """Answer ``n`` telemetry periods with ``controls``; return the last LOCAL_POSITION_NED."""
        last = None
        for _ in range(n):
            last = self.wait_for("LOCAL_POSITION_NED", on_msg=_collect(texts))
            self.target(controls)
        return last

    def close(self) -> None:
        self.sock.close()


class _KeptLink:
    """Stands for the UDP link: keeps every message sent."""

    def __init__(self):
        self.sent: list = []
        self.peers = [("127.0.0.1", 1)]

    def send(self, msgs):
        self.sent.extend(msgs)

    def recv_datagram(self):
        return None                          # nothing waits: messages are handed to the engine

    def close(self):
        pass


class Vehicle:
    """The command line's engine (ideal world, 500 Hz) with a kept link."""

    def __init__(self, *flags):
        args = build_parser().parse_args(["--listen", "udpin:127.0.0.1:0", "--world", "ideal", "--quiet",
                                          "--peer-system-id", str(GCS), *flags])
        self.engine, _ = build_engine(args)
        self.engine.link.close()
        self.engine.link = _KeptLink()
        self.ap = self.engine.ap
        self.codec = mavlink2.MAVLink(None, srcSystem=GCS, srcComponent=190)

    def send(self, msg, system_id: int = GCS, component_id: int = 190):
        self.codec.srcSystem, self.codec.srcComponent = system_id, component_id
        decoded = self.codec.decode(bytearray(msg.pack(self.codec)))
        n = len(self.engine.link.sent)
        self.engine.receive([decoded])
        return self.engine.link.sent[n:]

    def command(self, command, *params, system_id: int = GCS):
        p = list(params) + [0.0] * (7 - len(params))
        return self.send(mavlink2.MAVLink_command_long_message(1, 1, command, 0, *p), system_id)

    def ack(self, command, *params, system_id: int = GCS):
        acks = [m for m in self.command(command, *params, system_id=system_id) if m.get_type() == "COMMAND_ACK"]
        assert len(acks) <= 1
        return acks[0].result if acks else None

    def run(self, seconds: float, each=None) -> list:
        """Step ``seconds`` of vehicle time; the messages sent meanwhile."""
        link = self.engine.link
        n = len(link.sent)
        for _ in range(int(round(seconds * self.engine.sim.params.rate_hz))):
            self.engine.begin_period()
            self.engine.step()
            if each is not None:
                each(self)
        return link.sent[n:]


def _collect(texts):
    if texts is None:
        return None

    def f(m):
        if m.get_type() == "STATUSTEXT":
            texts.append(m.text)
        elif m.get_type() == "HEARTBEAT":
            texts.append(("HB", m.base_mode, m.custom_mode))
    return f


ARM = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
SET_MODE = mavlink2.MAV_CMD_DO_SET_MODE


class SamplePairer:
    """Completes state samples as the daemon does: ATTITUDE_QUATERNION + LOCAL_POSITION_NED of one time."""

    def __init__(self):
        self.att: set = set()
        self.pos: set = set()
        self.last_ms = -1

    def add(self, m) -> int | None:
        """Feed one message; return the sample's ``time_boot_ms`` when it completes one."""
        kind = {"ATTITUDE_QUATERNION": self.att, "LOCAL_POSITION_NED": self.pos}.get(m.get_type())
        if kind is None or m.time_boot_ms <= self.last_ms:
            return None
        kind.add(m.time_boot_ms)
        t = m.time_boot_ms
        if t in self.att and t in self.pos:
            self.last_ms = t
            self.att = {x for x in self.att if x > t}
            self.pos = {x for x in self.pos if x > t}
            return t
        return None


def answer_samples(client: Client, on_sample, on_msg=None, until_ms: int | None = None, proc=None,
                   timeout_s: float = 10.0) -> None:
    """Lockstep peer: call ``on_sample(time_boot_ms)`` for every complete sample.

    ``on_sample`` must send exactly one actuator target (after any command). Stops after
    the sample of ``until_ms``, or when process ``proc`` has exited and nothing is left
    to read; raises after ``timeout_s`` of silence otherwise.
    """
    pairer = SamplePairer()
    silent_s = 0.0
    while until_ms is None or pairer.last_ms < until_ms:
        m = client.recv(0.2)
        if m is None:
            if proc is not None and proc.poll() is not None:
                return
            silent_s += 0.2
            if silent_s > timeout_s:
                raise AssertionError(f"no message within {timeout_s} s after sample {pairer.last_ms} ms")
            continue
        silent_s = 0.0
        if on_msg is not None:
            on_msg(m)
        t = pairer.add(m)
        if t is not None:
            on_sample(t)
