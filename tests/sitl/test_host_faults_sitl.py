"""The host misbehaves, end to end (issue 32, item 3): a full disk, a stepped wall clock.

Flights in lockstep on the bundled emulator (deterministic, independent of the machine's
load), judged on the emulator's recorded truth:

- every file ``mavreg fly`` writes is on a full disk (``/dev/full``: each write gives
  ``ENOSPC``): the flight is flown and landed ``ok``, exit 0, each file said once, and the
  summary reaches the user on standard output;
- the wall clock jumps by +1 h or -1 h as the maneuver begins (the injected clock,
  :attr:`mavreg.daemon.fly.FlyOptions.wall_s`): the flight is the same, bit for bit, as one
  without a jump; the signed link takes every frame; the ``.tlog``'s stamps step by nothing.
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER
from sitl_helpers import load_record, vehicle_samples
from tests.helpers.repo import ROOT

pytestmark = pytest.mark.sitl

HOP = Path(__file__).with_name("signing_hop.yaml")
FULL = Path("/dev/full")
OUTPUTS = ("flight.tlog", "control.npz", "summary.json", "flight.png")


def _landed_ok(record: dict) -> None:
    """The truth: flown off the ground and back, disarmed on the ground at the end, no crash."""
    z = record["position_ned_m"][:, 2]
    assert z.min() < -1.0 and abs(z[-1]) < 0.05
    assert not bool(record["armed"][-1])


@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")
def test_fly_with_every_output_on_a_full_disk_lands_ok_and_says_each_once(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for name in OUTPUTS:
        (out / name).symlink_to(FULL)
    res = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "fly", str(HOP), "--lockstep", "--out", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    err = res.stderr.splitlines()
    assert res.returncode == 0, res.stderr[-3000:]
    for what, name in (("tlog", "flight.tlog"), ("control log", "control.npz"), ("summary", "summary.json"),
                       ("plot", "flight.png")):
        said = [ln for ln in err if ln.startswith(f"{what}: stopped writing {out / name}")]
        assert len(said) == 1, (what, said)
        assert "[Errno 28 ENOSPC] No space left on device" in said[0]
    assert "Traceback" not in res.stderr
    summary_line = [ln for ln in res.stdout.splitlines() if ln.startswith("summary.json: ")]
    assert len(summary_line) == 1
    summary = json.loads(summary_line[0].split(": ", 1)[1])
    assert summary["result"] == "ok" and summary["status"]["tlog"]["stopped"].startswith("tlog: stopped writing")
    assert "not written: summary.json, flight.png, flight.tlog, control.npz" in res.stdout
    _landed_ok(load_record(out / "groundtruth.npz"))


def _fly_in_process(tmp_path: Path, jumps: bool, monkeypatch) -> dict:
    """The hop in lockstep, signed, through :func:`mavreg.daemon.fly.fly` in this process; with
    ``jumps`` its wall clock jumps +1 h as the maneuver begins and -2 h (to an hour behind) as
    the landing begins."""
    from mavreg.daemon import fly as fly_mod
    from mavreg.daemon.supervisor import Phase
    tmp_path.mkdir()
    key = tmp_path / "mavlink.key"
    key.write_text(bytes(range(7, 39)).hex())
    key.chmod(0o600)
    state = {"daemon": None, "offset_s": 0.0, "jumped_at": {}}
    steps = {Phase.MANEUVER: 3600.0, Phase.LAND: -7200.0} if jumps else {}

    def wall_s() -> float:
        d = state["daemon"]
        if d is not None and d.supervisor.phase in steps and d.supervisor.phase not in state["jumped_at"]:
            state["jumped_at"][d.supervisor.phase] = d.supervisor.last_sample.time_s
            state["offset_s"] += steps[d.supervisor.phase]
        return time.time() + state["offset_s"]

    class Watched(fly_mod.Daemon):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            state["daemon"] = self
    monkeypatch.setattr(fly_mod, "Daemon", Watched)
    out = tmp_path / "out"
    opts = fly_mod.FlyOptions(HOP, None, DEFAULT_VEHICLE, REAL_CONTROLLER, out, None, 600.0, True, (),
                              signing_key=key, tlog_clock="wall", wall_s=wall_s)
    started_s = time.time()
    code = fly_mod.fly(opts)
    saved = json.loads((tmp_path / "mavlink.key.mavreg-state.json").read_text())["timestamp"]
    return {"code": code, "summary": json.loads((out / "summary.json").read_text()),
            "record": load_record(out / "groundtruth.npz"), "jumped_at": state["jumped_at"],
            "tlog": vehicle_samples(out / "flight.tlog"),
            "signed_ahead_s": saved / 1e5 + 1_420_070_400 - started_s}


def test_wall_clock_jumps_of_an_hour_mid_flight_change_nothing(tmp_path, monkeypatch):
    from mavreg.daemon.supervisor import Phase
    ref = _fly_in_process(tmp_path / "steady", False, monkeypatch)
    jumped = _fly_in_process(tmp_path / "jumped", True, monkeypatch)
    for f in (ref, jumped):
        s = f["summary"]
        assert f["code"] == 0 and s["result"] == "ok", s["reason"]
        _landed_ok(f["record"])
        assert s["status"]["signing"]["accepted"] > 10_000
        assert all(s["status"]["signing"][k] == 0 for k in ("unsigned", "bad_signature", "replayed"))
        # the .tlog's stamps (the wall clock at the start, then the monotonic clock) never step
        d = np.diff(f["tlog"][:, 0])
        assert np.all(d >= 0) and np.max(d) < 60.0
    # the clock did jump: in the maneuver (10.0-13.1 s of the hop's vehicle time), then at the
    # landing; the signing timestamps took the hour ahead and did not go back with the clock
    assert 10.0 < jumped["jumped_at"][Phase.MANEUVER] < 13.2 < jumped["jumped_at"][Phase.LAND]
    assert jumped["signed_ahead_s"] > 3500.0 and ref["signed_ahead_s"] < 600.0
    # the same flight, sample for sample, as the one without a jump
    a, b = ref["record"], jumped["record"]
    n = min(len(a["t_s"]), len(b["t_s"]))
    dist = float(np.max(np.linalg.norm(a["position_ned_m"][:n] - b["position_ned_m"][:n], axis=1)))
    print(f"\n{len(b['t_s'])} samples against {len(a['t_s'])}; largest distance {dist:.3g} m; flight "
          f"{jumped['summary']['flight_time_s']:.3f} s against {ref['summary']['flight_time_s']:.3f} s")
    assert dist < 1e-3 and abs(len(a["t_s"]) - len(b["t_s"])) <= 5
