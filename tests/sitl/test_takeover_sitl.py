"""A daemon killed mid-maneuver and started again finds the vehicle still in the air, held by
its failsafe, and takes it back: the emulator (lockstep, its failsafe hold made long, as PX4's
``COM_OBL_RC_ACT`` Hold is) and two ``mavreg fly`` processes, judged by the emulator's ground
truth (docs/safety.md, *Taking over an airborne vehicle*)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from tests.helpers.sitl import BARREL, CONTROLLER, load_record, mavreg, start_emulator
from mavreg.daemon.jobs.endpoint import request

pytestmark = [pytest.mark.sitl, pytest.mark.slow]   # about 45 s: the failsafe hold runs in real time

OFFBOARD = 6 << 16
HOLD = (3 << 24) | (4 << 16)


def _kill_mid_maneuver(url: str, out, sock) -> float:
    """Fly the barrel roll and SIGKILL the daemon inside the loop; the arc length then."""
    fly = mavreg("fly", str(BARREL), "--vehicle", url, "--vehicle-lockstep", "--out", str(out),
                 "--controller", str(CONTROLLER), "--socket", str(sock))
    try:
        fly.wait_line("[maneuver] phase", 200)
        for _ in range(20000):
            st = request(sock, {"op": "status"}, 10)["status"]
            if st["s_m"] is not None and st["s_m"] > 21.0:
                return st["s_m"]
        raise AssertionError("the maneuver ended before the kill")
    finally:
        fly.stop(sig=9)


def test_a_restarted_daemon_takes_the_airborne_vehicle_back_and_lands_it(tmp_path):
    record = tmp_path / "gt.npz"
    emu, url = start_emulator(record, "--lockstep", "--world", "ideal", "--failsafe-hold-s", "120",
                              "--lockstep-stall-factor", "1.0")
    try:
        s_kill = _kill_mid_maneuver(url, tmp_path / "first", tmp_path / "first.sock")
        again = mavreg("fly", str(BARREL), "--vehicle", url, "--vehicle-lockstep", "--out", str(tmp_path / "again"),
                       "--controller", str(CONTROLLER), "--socket", str(tmp_path / "again.sock"))
        code = again.wait(300)
    finally:
        again_lines = again.lines if "again" in locals() else []
        emu.stop()
    assert code == 1, "\n".join(again_lines[-20:])          # landed, the maneuver not flown: not a success
    summary = json.loads((tmp_path / "again" / "summary.json").read_text())
    phases = [e["phase"] for e in summary["events"] if e["kind"] == "phase"]
    assert phases == ["takeover", "recover", "land", "disarmed"], phases
    rec = load_record(record)
    t, armed, ground = rec["t_s"], rec["armed"].astype(bool), rec["on_ground"].astype(bool)
    lift = np.flatnonzero(~ground)[0]
    last_air = np.flatnonzero(~ground)[-1]
    assert armed[lift:last_air + 1].all(), "disarmed in the air"
    assert not armed[-1] and ground[-1]                        # landed and disarmed
    # the second daemon found it held by the failsafe, and never armed it again
    off = np.flatnonzero(armed & (rec["custom_mode"] == OFFBOARD))
    gap = np.flatnonzero(np.diff(off) > 1)[0]                  # the first daemon's stream lost
    between = rec["custom_mode"][off[gap] + 1:off[gap + 1]]
    assert HOLD in set(between.tolist()) and not ground[off[gap] + 1:off[gap + 1]].any()
    before = (t >= t[last_air] - 0.5) & (t <= t[last_air])    # the descent's last half second
    touchdown_m_s = float(rec["velocity_ned_m_s"][before, 2].max())
    print(f"\nkilled at s={s_kill:.1f} m; taken back {t[off[gap + 1]] - t[off[gap]]:.1f} s later at "
          f"{-rec['position_ned_m'][off[gap + 1], 2]:.1f} m; touchdown {touchdown_m_s:.2f} m/s")
    assert touchdown_m_s < 1.0
