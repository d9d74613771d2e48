"""Fly a campaign through one ``mavreg serve``: the soak and the chaos campaign.

``mavreg experiment soak|chaos`` (docs/reliability.md). One ``serve`` process against the
bundled emulator in lockstep flies every flight of :func:`~.serve_draws.draw_flights`,
uploads through its control endpoint as a user would (``mavreg upload``'s requests):

1. (chaos) the emulator restarts in the flight's world, recording its truth;
2. the hostile uploads, each of which must be rejected;
3. the flight's upload (its laps rewritten as ``mavreg upload --laps`` does), the host loaded
   on every core when drawn, until the maneuver is flown or the flight ends; then ``land``,
   until the daemon's record of the flight appears in its status.

After each flight it samples the ``serve`` process and its planner worker (resident memory,
descriptors, threads: Linux's ``/proc``). A flight whose record never comes (within
``flight_timeout_s`` of wall time, or the daemon gone) is a **lost result**. A chaos flight
is judged on the emulator's recording too (:func:`~.robustness_metrics.judge_flight`'s
touchdowns and motors stopped in the air) and on arming: the vehicle armed with no upload
accepted is an arm not asked for.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from ..config.maneuver import maneuver_text_with_laps
from ..config.paths import DEFAULT_VEHICLE, maneuver_file
from ..daemon.jobs.endpoint import request
from ..daemon.jobs.fly import spawn_emulator, stop_process
from ..daemon.jobs.lifeline import wrap_command
from .serve_draws import HOP_YAML, HOSTILE_UPLOADS, FlightDraw

__all__ = ["ServeRig", "fly_campaign", "process_sample"]

REQUEST_TIMEOUT_S = 600.0
KEEP_LOGS = 5
"""serve's --keep-logs in a campaign: the logs left at the end are the newest 5 .tlog and 5
controller logs."""
POLL_S = 0.2


def process_sample(pid: int) -> dict:
    """Resident memory (kB), open descriptors and threads of ``pid`` (Linux ``/proc``)."""
    status = Path(f"/proc/{pid}/status").read_text()
    fields = dict(line.split(":", 1) for line in status.splitlines() if ":" in line)
    return {"rss_kb": int(fields["VmRSS"].split()[0]), "threads": int(fields["Threads"]),
            "fds": len(os.listdir(f"/proc/{pid}/fd"))}


class ServeRig:
    """The emulator and ``serve`` as processes; uploads and status through the endpoint."""

    def __init__(self, out_dir: Path, rate_hz: float, serve_args: tuple[str, ...] = ()):
        self.out_dir = Path(out_dir)
        self.rate_hz = rate_hz
        self.socket = self.out_dir / "serve.sock"
        self.emulator: subprocess.Popen | None = None
        self.url: str | None = None
        self.serve_args = serve_args
        self.serve: subprocess.Popen | None = None
        self._serve_log = None

    def start_emulator(self, world: tuple[str, ...], record: Path | None) -> None:
        """(Re)start the emulator on the same port (the first start picks a free one)."""
        extra = world
        if self.url is not None:
            extra += ("--listen", "udpin:" + self.url.split(":", 1)[1])
            stop_process(self.emulator)
        self.emulator, url = spawn_emulator(DEFAULT_VEHICLE, record, True, extra, timeout_s=120.0,
                                            rate_hz=self.rate_hz, preset="ideal")
        self.url = self.url or url

    def start_serve(self) -> None:
        self._serve_log = open(self.out_dir / "serve.log", "w")
        cmd = [sys.executable, "-m", "mavreg.cli.main", "serve", "--vehicle", self.url, "--vehicle-lockstep",
               "--socket", str(self.socket), "--control-rate-hz", f"{self.rate_hz:g}",
               "--stale-timeout-s", "5", *self.serve_args]
        # bound to this process (the parent-death signal): a campaign killed leaves no serve behind
        self.serve = subprocess.Popen(wrap_command(cmd), stdout=self._serve_log, stderr=subprocess.STDOUT,
                                      start_new_session=True)
        deadline = time.monotonic() + REQUEST_TIMEOUT_S
        while time.monotonic() < deadline and self.serve.poll() is None:
            try:
                self.status()
                return
            except OSError:
                time.sleep(POLL_S)
        raise RuntimeError(f"mavreg serve did not start (exit {self.serve.poll()}); see {self.out_dir}/serve.log")

    def status(self) -> dict:
        return request(self.socket, {"op": "status"}, REQUEST_TIMEOUT_S)["status"]

    def upload(self, name: str, text: str) -> dict:
        return request(self.socket, {"op": "upload", "name": name, "yaml": text}, REQUEST_TIMEOUT_S)

    def land(self) -> dict:
        return request(self.socket, {"op": "land"}, REQUEST_TIMEOUT_S)

    def resources(self) -> dict:
        """The serve process's and its planner worker's :func:`process_sample` (the worker's pid
        from the daemon's own status, not guessed among its children)."""
        sample = {"serve": process_sample(self.serve.pid)}
        worker = (self.status().get("planner") or {}).get("worker_pid")
        if worker is not None:
            try:
                sample["worker"] = process_sample(worker)
            except OSError:
                pass                    # it ended between the status and the reading
        return sample

    def stop(self) -> int | None:
        code = None
        if self.serve is not None and self.serve.poll() is None:
            self.serve.send_signal(signal.SIGTERM)
            try:
                code = self.serve.wait(120)
            except subprocess.TimeoutExpired:
                self.serve.kill()
                code = self.serve.wait()
        elif self.serve is not None:
            code = self.serve.returncode
        if self.emulator is not None:
            stop_process(self.emulator)
        if self._serve_log is not None:
            self._serve_log.close()
        return code


def upload_text(draw: FlightDraw) -> str:
    text = HOP_YAML if draw.maneuver == "hop" else maneuver_file(draw.maneuver).read_text()
    return text if draw.laps is None else maneuver_text_with_laps(text, draw.laps, draw.maneuver)


class _Load:
    """Busy loops on every core, from :meth:`start` to :meth:`stop`."""

    def __init__(self):
        self.procs: list[subprocess.Popen] = []

    def start(self) -> None:
        for _ in range(os.cpu_count() or 1):
            self.procs.append(subprocess.Popen(wrap_command([sys.executable, "-c", "while True: pass"]),
                                               start_new_session=True))

    def stop(self) -> None:
        for p in self.procs:
            p.kill()
            p.wait()
        self.procs.clear()


def _wait_record(rig: ServeRig, flown_before: int, timeout_s: float) -> dict | None:
    """The daemon's record of the flight under way: the maneuver flown (or the flight over),
    then ``land``, until the record appears. None: lost (timeout, or the daemon gone)."""
    deadline = time.monotonic() + timeout_s
    landed_asked = False
    while time.monotonic() < deadline and rig.serve.poll() is None:
        st = rig.status()
        flights = st["flights"]
        if flights["flown"] > flown_before:
            return flights["last"][-1] | {"status_counters": st["counters"]}
        if not landed_asked and (st["done"] or st["phase"] in ("recover",)):
            rig.land()
            landed_asked = True
        time.sleep(POLL_S)
    return None


def _wait_ready(rig: ServeRig, timeout_s: float) -> int | None:
    """Wait, as a user would, until the daemon takes a new flight (after an aborted one it waits
    for the vehicle to disarm); the flights flown so far, or None (timeout, daemon gone)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and rig.serve.poll() is None:
        flights = rig.status()["flights"]
        if not flights["waiting_for_disarm"]:
            return flights["flown"]
        time.sleep(POLL_S)
    return None


def fly_one(rig: ServeRig, draw: FlightDraw, timeout_s: float) -> dict:
    """One flight of the campaign (see the module docstring); its row."""
    row: dict = {"flight": draw.number, "draw": draw.describe(), "maneuver": draw.maneuver, "laps": draw.laps}
    row["hostile"] = {}
    for name in draw.hostile:
        reply = rig.upload(f"{name}.yaml", HOSTILE_UPLOADS[name])
        row["hostile"][name] = "rejected" if reply.get("verdict") == "rejected" else f"NOT rejected: {reply}"
    flown_before = _wait_ready(rig, timeout_s)
    if flown_before is None:
        row.update(record=None, upload="not sent")
        if rig.serve.poll() is None:
            row["not_flown"] = ("the vehicle never reported itself disarmed after the aborted flight before "
                                "(its own failsafe holds it armed); the daemon waits for that, as it must")
        else:
            row["lost"] = "the daemon is gone"
        return row
    load = _Load()
    try:
        reply = rig.upload(f"{draw.maneuver}.yaml", upload_text(draw))
        row["upload"] = reply.get("verdict") or reply.get("error")
        if not reply.get("ok"):
            row["upload_reason"] = reply.get("reason") or reply.get("error")
            row["record"] = None
            return row
        if draw.load:
            load.start()
        row["record"] = _wait_record(rig, flown_before, timeout_s)
    finally:
        load.stop()
    return row


def fly_campaign(draws: list[FlightDraw], out_dir: Path, rate_hz: float = 250.0,
                 flight_timeout_s: float = 900.0, say=print, judge=None, on_row=None) -> dict:
    """Fly ``draws`` through one ``serve``; the rows, the resource samples and the daemon's exit.

    ``judge(rows, record_path)`` (chaos) judges the flights of one world on the emulator's
    recording once the emulator has saved it (at its restart into the next world, or at the end).
    ``on_row(rows)`` is called after each flight (the campaign so far, written as it goes).
    """
    out_dir = Path(out_dir)
    runs = out_dir / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    logs = out_dir / "logs"
    logs.mkdir(exist_ok=True)
    rig = ServeRig(out_dir, rate_hz, ("--out", str(logs), "--keep-logs", str(KEEP_LOGS)))
    rows: list[dict] = []
    pending_judge: tuple[list[dict], Path] | None = None
    t0 = time.monotonic()
    code = None
    try:
        first = draws[0]
        truth = runs / f"{first.number:04d}-truth.npz" if judge else None
        rig.start_emulator(first.world, truth)
        rig.start_serve()
        for draw in draws:
            if draw.restart and draw.number != first.number:
                truth = runs / f"{draw.number:04d}-truth.npz" if judge else None
                rig.start_emulator(draw.world, truth)       # the last world's recording is saved
                if pending_judge is not None:
                    judge(*pending_judge)
                    pending_judge = None
            if rig.serve.poll() is not None:
                rows.append({"flight": draw.number, "draw": draw.describe(), "record": None,
                             "lost": f"mavreg serve exited ({rig.serve.returncode})"})
                continue
            row = fly_one(rig, draw, flight_timeout_s)
            row["wall_s"] = time.monotonic() - t0
            row["resources"] = rig.resources() if rig.serve.poll() is None else None
            rows.append(row)
            if judge and truth is not None:
                pending_judge = (pending_judge or ([], truth))
                pending_judge[0].append(row)
            rec = row["record"]
            if on_row is not None:
                on_row(rows)
            say(f"flight {draw.number}/{len(draws)} ({draw.describe()}): "
                + (rec["result"] if rec else f"no record ({row.get('upload_reason') or 'lost'})")
                + f"; {row['wall_s']:.0f} s")
    finally:
        code = rig.stop()
        if pending_judge is not None:
            judge(*pending_judge)
    return {"rows": rows, "serve_exit": code, "wall_s": time.monotonic() - t0,
            "log_files": sorted(p.name for p in logs.iterdir())}
