"""Rate mode, as PX4 OFFBOARD: SET_ATTITUDE_TARGET body rates and collective thrust, flown by the
emulator's own rate loop (docs/firmware_sim.md, "Rate mode, as PX4 OFFBOARD").

In process and in vehicle time (the command line's engine with a kept link, one control period at a
time), but for one lockstep flight over UDP."""
from __future__ import annotations

import json
import math
import re
from functools import lru_cache

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as M

from firmware_sim import modes
from firmware_sim.cli import build_parser, main
from firmware_sim.rate_loop import ROLL_PITCH_UNIT, YAW_UNIT, allocate, collective_thrust_n

from tests.helpers.emulator import REPO, Client, Emulator, Vehicle, answer_samples

DAEMON = (1, 191)
MASS_KG, FMAX_N, E, L_M = 0.749, 12.0, 0.3, 0.30       # params/vehicles/mk_quadro.yaml, THR_MDL_FAC


def _hover_thrust(e=E) -> float:
    """The root of 4 f_max ((1 - e) t + e t^2) = m g, solved here on its own."""
    y = MASS_KG * 9.81 / (4 * FMAX_N)
    return y if e == 0 else (-(1 - e) + math.sqrt((1 - e) ** 2 + 4 * e * y)) / (2 * e)


T_HOVER = _hover_thrust()


def rates_msg(p=0.0, q=0.0, r=0.0, thrust=T_HOVER, mask=128, target_system=1):
    return M.MAVLink_set_attitude_target_message(0, target_system, 1, mask, (1.0, 0.0, 0.0, 0.0), p, q, r, thrust)


def fly(v: Vehicle, seconds: float, setpoint, every_period=True) -> tuple:
    """Step ``seconds``, sending ``setpoint(t, state)`` (p, q, r, thrust) from the daemon's ids each
    period (``None``: nothing); the true states at the period starts and their times."""
    e = v.engine
    ts, states = [], []
    for _ in range(int(round(seconds * e.sim.params.rate_hz))):
        e.begin_period()
        sp = setpoint(e.sim.t_s, e.sim.state)
        if sp is not None:
            v.send(rates_msg(*sp), *DAEMON)
        e.step()
        ts.append(e.sim.t_s)
        states.append(e.sim.state)
    return np.asarray(ts), np.asarray(states)


def _crossing(t, y, level) -> float:
    i = int(np.argmax(y >= level))
    assert y[i] >= level, f"never reached {level}"
    return float(t[i - 1] + (level - y[i - 1]) * (t[i] - t[i - 1]) / (y[i] - y[i - 1]))


def measured_step(*flags, axis=0, step=1.0, thrust=T_HOVER) -> dict:
    """A step of ``step`` rad/s on ``axis`` flown in the realistic world (estimator errors on, the
    uplink without delay so that the receipt is the send), from hover; times after the receipt."""
    v = Vehicle("--start", "z_m=-30", "--world", "realistic", "--command-delay-s", "0",
                "--command-jitter-s", "0", "--loss", "0", *flags)
    _, before = fly(v, 0.4, lambda t, s: (0.0, 0.0, 0.0, thrust))
    w0 = float(np.mean(before[-50:, 10 + axis]))        # the loop holds the gyro's bias: from there
    t0 = v.engine.sim.t_s
    sp = [0.0, 0.0, 0.0, thrust]
    sp[axis] = step
    t, s = fly(v, 0.6, lambda t, s: tuple(sp))
    t = np.concatenate(([t0], t)) - t0
    y = (np.concatenate(([w0], s[:, 10 + axis])) - w0) / step
    final = float(np.mean(y[t >= 0.3]))
    return {"t10": _crossing(t, y, 0.1), "t50": _crossing(t, y, 0.5), "t90": _crossing(t, y, 0.9),
            "overshoot": float(np.max(y)) - final, "final": final, "others": s[:, 10:13], "v": v}


@lru_cache(maxsize=None)
def _default_step():
    return measured_step()


# ---------------------------------------------------------------- thrust map
def test_thrust_map_round_trips_and_mpc_thr_hover_is_the_hover_collective():
    from firmware_sim.rate_loop import hover_thrust, thrust_for_force
    for e in (0.0, 0.3, 1.0):
        for t in np.linspace(0.0, 1.0, 21):
            f = collective_thrust_n(t, e, FMAX_N)
            assert f == pytest.approx(4 * FMAX_N * ((1 - e) * t + e * t * t))
            assert thrust_for_force(f, e, FMAX_N) == pytest.approx(t, abs=1e-12)
        assert hover_thrust(MASS_KG, e, FMAX_N) == pytest.approx(_hover_thrust(e), abs=1e-12)
    v = Vehicle()
    read = {m.param_id: m.param_value for m in v.send(M.MAVLink_param_request_list_message(1, 1))}
    assert read["MPC_THR_HOVER"] == pytest.approx(T_HOVER, abs=1e-6) and read["THR_MDL_FAC"] == pytest.approx(E)
    assert read["MC_ROLLRATE_P"] > 0 and "MC_YAWRATE_FF" in read and read["COM_OF_LOSS_T"] == 0.25
    out = v.send(M.MAVLink_param_set_message(1, 1, b"MPC_THR_HOVER", 0.5, M.MAV_PARAM_TYPE_REAL32))
    assert [m.param_value for m in out if m.get_type() == "PARAM_VALUE"] == [pytest.approx(T_HOVER, abs=1e-6)]
    assert any("read only" in m.text for m in out if m.get_type() == "STATUSTEXT")
    assert v.ap.drops["unsupported"] == 1
    v.send(M.MAVLink_param_set_message(1, 1, b"THR_MDL_FAC", 0.0, M.MAV_PARAM_TYPE_REAL32))
    out = v.send(M.MAVLink_param_request_read_message(1, 1, b"MPC_THR_HOVER", -1))
    assert out[0].param_value == pytest.approx(_hover_thrust(0.0), abs=1e-6)     # linear: m g / (4 f_max)


def test_the_gains_are_parameters_that_act():
    v = Vehicle("--start", "z_m=-20")
    fly(v, 0.1, lambda t, s: (0.0, 0.0, 0.0, T_HOVER))
    _, s = fly(v, 0.1, lambda t, s: (1.0, 0.0, 0.0, T_HOVER))
    assert s[-1, 10] > 0.8                                     # the default gains fly the step
    for name in (b"MC_ROLLRATE_P", b"MC_ROLLRATE_I", b"MC_ROLLRATE_D"):
        out = v.send(M.MAVLink_param_set_message(1, 1, name, 0.0, M.MAV_PARAM_TYPE_REAL32))
        assert [m.param_value for m in out if m.get_type() == "PARAM_VALUE"] == [0.0]
    out = v.send(M.MAVLink_param_set_message(1, 1, b"MC_ROLLRATE_P", 11.0, M.MAV_PARAM_TYPE_REAL32))
    assert [m.param_value for m in out if m.get_type() == "PARAM_VALUE"] == [0.0]     # beyond 10: refused
    _, s = fly(v, 0.1, lambda t, s: (0.0, 0.0, 0.0, T_HOVER))
    w = s[-1, 10]
    _, s = fly(v, 0.2, lambda t, s: (-1.0, 0.0, 0.0, T_HOVER))
    assert abs(s[-1, 10] - w) < 0.05 and v.ap.rates.cfg.roll_p == 0.0   # no roll gain, no roll


@pytest.mark.parametrize("preset", ["ideal", "realistic"])
def test_hover_at_the_hover_thrust_holds_altitude_and_a_linear_model_does_not(preset):
    v = Vehicle("--start", "z_m=-20", "--world", preset)
    _, s = fly(v, 5.0, lambda t, s: (0.0, 0.0, 0.0, T_HOVER))
    assert abs(s[-1, 2] - s[0, 2]) < 0.1 and v.ap.mode == modes.OFFBOARD and v.ap.rate_mode
    # negative control: the hover collective of a linear thrust map (e = 0) is too low for this one
    v = Vehicle("--start", "z_m=-100", "--world", preset)
    _, s = fly(v, 5.0, lambda t, s: (0.0, 0.0, 0.0, _hover_thrust(0.0)))
    assert s[-1, 2] - s[0, 2] > 3.0                                 # sinks metres in 5 s


# ---------------------------------------------------------------- step responses
def test_roll_rate_step_meets_the_documented_bounds():
    m = _default_step()
    assert 0.005 <= m["t10"] <= 0.020 and 0.015 <= m["t50"] <= 0.035 and 0.030 <= m["t90"] <= 0.060
    assert 0.020 <= m["t90"] - m["t10"] <= 0.040               # 10-90 % rise
    assert m["overshoot"] <= 0.10 and abs(m["final"] - 1.0) <= 0.03
    assert np.max(np.abs(m["others"][:, 1:])) < 0.1             # pitch and yaw stay near 0


def test_the_processing_latency_delays_the_response_by_itself():
    base, late = _default_step(), measured_step("--rate-latency-s", "0.02")
    for k in ("t10", "t50", "t90"):
        assert late[k] - base[k] == pytest.approx(0.018, abs=0.0015)


def test_yaw_rate_step_and_its_sign():
    """0.15 rad/s: within yaw's authority at hover (larger steps are rate-limited, see the docs)."""
    for step in (0.15, -0.15):
        m = measured_step(axis=2, step=step)
        assert m["t50"] <= 0.08 and m["overshoot"] <= 0.10 and abs(m["final"] - 1.0) <= 0.03
        assert np.sign(m["others"][-1, 2]) == np.sign(step)
        assert np.max(np.abs(m["others"][:, :2])) < 0.1


def _pair_units(u) -> tuple:
    """Torques in units of a rotor pair differing by f_max (so roll ``u`` is ``u l f_max``) as
    PX4's normalized torques of the allocation (a unit moves each rotor by ROLL_PITCH_UNIT f_max,
    yaw by YAW_UNIT f_max)."""
    return (u[0] / (2 * ROLL_PITCH_UNIT), u[1] / (2 * ROLL_PITCH_UNIT), u[2] / (2 * YAW_UNIT))


def test_the_torque_units_are_px4s_normalized_allocation():
    """PX4's allocator: the pseudo-inverse of the effectiveness matrix, its roll and pitch
    columns scaled to a norm squared of half their nonzero entries, yaw's to a largest entry of
    1 (ControlAllocationPseudoInverse); computed here for the emulator's '+' frame and for SIH's
    X frame, where every rotor moves by 1/sqrt 2 of f_max per unit roll."""
    for frame in ("+", "x"):
        xy = [(1, 0), (0, 1), (-1, 0), (0, -1)] if frame == "+" else [(1, 1), (-1, 1), (-1, -1), (1, -1)]
        B = np.array([[-y for x, y in xy], [x for x, y in xy], [-1, 1, -1, 1], [1, 1, 1, 1]], float)
        mix = np.linalg.pinv(B)
        for j in (0, 1):
            mix[:, j] /= np.sqrt(np.sum(mix[:, j] ** 2) / (np.count_nonzero(np.abs(mix[:, j]) > 1e-3) / 2))
        mix[:, 2] /= mix[:, 2].max()
        moved = np.abs(mix[:, :3])
        for j in (0, 1):
            assert np.allclose(moved[moved[:, j] > 1e-3, j], ROLL_PITCH_UNIT)
        assert np.allclose(moved[:, 2], YAW_UNIT)
    base, _ = allocate(T_HOVER, (0.0, 0.0, 0.0), E, FMAX_N)
    f, _ = allocate(T_HOVER, (0.2, 0.0, 0.0), E, FMAX_N)
    assert f[3] - base[3] == pytest.approx(0.2 * ROLL_PITCH_UNIT * FMAX_N)        # left rotor up
    assert f[1] - base[1] == pytest.approx(-0.2 * ROLL_PITCH_UNIT * FMAX_N)
    f, _ = allocate(T_HOVER, (0.0, 0.0, 0.05), E, FMAX_N)
    assert f[1] - base[1] == pytest.approx(0.05 * YAW_UNIT * FMAX_N)


def test_a_large_roll_command_at_high_collective_keeps_its_roll_torque():
    for t, u in ((0.95, (0.6, 0.0, 0.5)), (0.02, (-0.6, 0.3, -0.4)), (T_HOVER, (1.5, 0.0, 0.0))):
        f, sat = allocate(t, _pair_units(u), E, FMAX_N)
        roll = min(1.0, max(-1.0, u[0]))
        assert all(0.0 <= x <= FMAX_N for x in f)
        assert L_M * (f[3] - f[1]) == pytest.approx(roll * L_M * FMAX_N)            # roll kept
        assert L_M * (f[0] - f[2]) == pytest.approx(u[1] * L_M * FMAX_N)            # pitch kept
        assert sat[0] == (0 if abs(u[0]) <= 1 else 1)
    f, sat = allocate(0.95, _pair_units((0.6, 0.0, 0.5)), E, FMAX_N)
    assert sum(f) < collective_thrust_n(0.95, E, FMAX_N) and sat[2] == 1          # collective and yaw gave way
    # negative control: clipping each rotor of the plain mix loses most of the roll torque
    c, d = collective_thrust_n(0.95, E, FMAX_N) / 4, 0.6 * FMAX_N / 2
    naive = [min(FMAX_N, max(0.0, x)) for x in (c, c - d, c, c + d)]
    assert naive[3] - naive[1] < 0.65 * (f[3] - f[1])
    # and in flight: a 3 rad/s roll step at a high collective comes as fast as at hover
    hover, high = measured_step(step=3.0), measured_step(step=3.0, thrust=0.8)
    assert high["t50"] == pytest.approx(hover["t50"], abs=0.003)


def test_the_printed_true_response_matches_a_flight_and_the_docs(capsys):
    assert main(["--print-rate-response"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4 and f"MPC_THR_HOVER {T_HOVER:.4f} (file)" in lines[0]
    roll = [float(x) for x in re.search(r"10/50/90 % at ([\d.]+)/([\d.]+)/([\d.]+) ms", lines[1]).groups()]
    m = _default_step()          # receipts on a tick: up to one physics step earlier than the mean
    for printed, k in zip(roll, ("t10", "t50", "t90")):
        assert 1e3 * m[k] == pytest.approx(printed, abs=1.5)
    doc = (REPO / "docs" / "firmware_sim.md").read_text()
    for line in lines:
        assert line in doc, f"docs/firmware_sim.md lacks the printed line {line!r}"
    assert "--print-rate-response" in build_parser().format_help()


def test_the_mismatch_draw_changes_the_rate_response(capsys):
    """Seed 3 draws a 41 ms motor lag (file: 20 ms): the loop, tuned on the file, is slower there."""
    assert main(["--print-rate-response", "--world", "ideal", "--mismatch-seed", "3"]) == 0
    drawn = capsys.readouterr().out
    assert main(["--print-rate-response", "--world", "ideal"]) == 0
    nominal = capsys.readouterr().out
    t50 = [float(re.search(r"rate response roll .*?10/50/90 % at [\d.]+/([\d.]+)", o).group(1))
           for o in (drawn, nominal)]
    assert t50[0] > t50[1] + 5.0
    assert re.search(r"\(file\), ([\d.]+) \(true airframe\)", drawn).group(1) != f"{T_HOVER:.4f}"


# ---------------------------------------------------------------- the message
def test_refused_masks_foreign_peers_and_bad_values_are_counted_never_applied():
    v = Vehicle("--start", "z_m=-20")
    fly(v, 0.2, lambda t, s: (0.0, 0.0, 0.0, T_HOVER))
    ap = v.ap
    texts = []
    for mask in (0, 7, 64 | 128, 128 | 7, 255, 1):
        texts += [m.text for m in v.send(rates_msg(p=3.0, mask=mask), *DAEMON) if m.get_type() == "STATUSTEXT"]
    assert ap.drops["unsupported"] == 6 and len(texts) == 1 and "type_mask 0 refused" in texts[0]
    fly(v, 1.0, lambda t, s: (0.0, 0.0, 0.0, T_HOVER))
    texts = [m.text for m in v.send(rates_msg(mask=0), *DAEMON) if m.get_type() == "STATUSTEXT"]
    assert len(texts) == 1 and ap.drops["unsupported"] == 7            # again after a second
    n0 = ap.target_count
    v.send(rates_msg(p=3.0))                                           # a ground station's (MAVSDK)
    v.send(rates_msg(p=3.0), 1, 190)                                   # another component
    v.send(rates_msg(p=3.0, target_system=2), *DAEMON)
    for bad in (rates_msg(p=math.nan), rates_msg(thrust=math.inf), rates_msg(p=25.0), rates_msg(thrust=1.1),
                rates_msg(thrust=-0.01)):
        v.send(bad, *DAEMON)
    d = ap.drops
    assert (d["foreign_system"], d["foreign_component"], d["wrong_target"]) == (1, 1, 1)
    assert (d["non_finite"], d["out_of_range"]) == (2, 3) and ap.target_count == n0
    _, s = fly(v, 0.3, lambda t, s: None)
    assert np.max(np.abs(s[:, 10])) < 0.05                             # no 3 rad/s roll was ever flown


def test_the_last_setpoint_kind_wins():
    v = Vehicle("--start", "z_m=-20")
    e, ap = v.engine, v.ap
    fly(v, 0.1, lambda t, s: (0.0, 0.0, 0.0, 0.5))
    assert ap.rate_mode and sum(ap.rates.output_n) == pytest.approx(collective_thrust_n(0.5, E, FMAX_N), rel=0.02)
    v.send(M.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, [0.25] * 4 + [0.0] * 4), *DAEMON)
    assert not ap.rate_mode and ap.rotor_command_n(e.sim.state, False, e.sim.t_s) == (3.0,) * 4
    v.send(rates_msg(thrust=0.3), *DAEMON)
    assert ap.rotor_command_n(e.sim.state, False, e.sim.t_s) == (3.0,) * 4      # within the latency
    fly(v, 0.01, lambda t, s: (0.0, 0.0, 0.0, 0.3))
    assert ap.rate_mode and sum(ap.rates.output_n) == pytest.approx(collective_thrust_n(0.3, E, FMAX_N), rel=0.02)
    v.send(M.MAVLink_set_position_target_local_ned_message(0, 1, 1, 1, 0b110111111000, 0, 0, -20, 0, 0, 0,
                                                           0, 0, 0, 0, 0), *DAEMON)
    assert not ap.rate_mode and ap.setpoint is not None and ap.rates.setpoint is None


def test_offboard_loss_with_rate_setpoints_fails_safe_and_lands():
    v = Vehicle("--start", "z_m=-2")
    fly(v, 0.5, lambda t, s: (0.0, 0.0, 0.0, T_HOVER))
    sent = len(v.engine.link.sent)
    fly(v, 0.2, lambda t, s: None)
    assert v.ap.mode == modes.OFFBOARD                 # negative control: within COM_OF_LOSS_T
    _, s = fly(v, 6.0, lambda t, s: None)
    texts = [m.text for m in v.engine.link.sent[sent:] if m.get_type() == "STATUSTEXT"]
    assert texts[:3] == ["mode HOLD: offboard lost, failsafe hold", "mode LAND: failsafe land", "disarmed: landed"]
    assert not v.ap.armed and v.engine.sim.on_ground and np.max(s[:, 2]) <= 0.0


def test_take_off_from_the_ground_hover_and_land_on_rate_setpoints():
    v = Vehicle("--world", "realistic")

    def pilot(t, s, thrust):                  # the test is the offboard controller: level, thrust
        qw, qx, qy = s[3], s[4], s[5]
        return (-8.0 * 2 * qx * np.sign(qw), -8.0 * 2 * qy * np.sign(qw), 0.0, min(1.0, max(0.0, thrust)))
    fly(v, 0.6, lambda t, s: pilot(t, s, 0.0))            # stream first, as PX4 asks
    v.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)       # taken after the realistic uplink's delay
    fly(v, 0.02, lambda t, s: pilot(t, s, 0.0))
    v.command(M.MAV_CMD_DO_SET_MODE, 1, 6)
    fly(v, 0.02, lambda t, s: pilot(t, s, 0.0))
    assert v.ap.armed and v.ap.mode == modes.OFFBOARD
    sent = len(v.engine.link.sent)
    t0 = v.engine.sim.t_s
    fly(v, 1.5, lambda t, s: pilot(t, s, min(1.0, (t - t0) / 0.5) * (T_HOVER + 0.06)))     # ramp up
    assert v.engine.sim.state[2] < -1.0 and not v.engine.sim.on_ground
    _, s = fly(v, 6.0, lambda t, s: pilot(t, s, T_HOVER + 0.3 * (s[9] - 0.5)))            # down at 0.5 m/s
    touchdown = int(np.argmax(s[:, 2] >= 0.0))
    assert v.engine.sim.on_ground and v.ap.armed and 0.3 < s[touchdown - 1, 9] < 0.7     # at 0.5 m/s
    fly(v, 0.5, lambda t, s: pilot(t, s, 0.0))
    states = [m.landed_state for m in v.engine.link.sent[sent:] if m.get_type() == "EXTENDED_SYS_STATE"]
    flown = [k for i, k in enumerate(states) if i == 0 or k != states[i - 1]]
    assert flown == [M.MAV_LANDED_STATE_ON_GROUND, M.MAV_LANDED_STATE_IN_AIR, M.MAV_LANDED_STATE_ON_GROUND]
    v.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    fly(v, 0.02, lambda t, s: pilot(t, s, 0.0))
    assert not v.ap.armed


def test_rate_setpoints_pace_the_lockstep_in_the_realistic_world(tmp_path):
    """Each complete sample answered with one SET_ATTITUDE_TARGET: no period waits in vain."""
    with Emulator("--lockstep", "--start", "z_m=-10", "--duration-s", "1.5", record=tmp_path / "g.npz") as emu:
        c = Client(emu.port)
        c.heartbeat()
        last = {}

        def on_msg(m):
            if m.get_type() == "LOCAL_POSITION_NED":
                last["z"] = m.z
            elif m.get_type() == "HEARTBEAT":
                last["mode"] = m.custom_mode
        answer_samples(c, lambda t_ms: c.send(rates_msg()), on_msg, proc=emu.proc)
        code = emu.stop()
        c.close()
    with np.load(tmp_path / "g.npz") as z:
        meta = json.loads(str(z["meta_json"]))
    counters = meta["counters"]
    assert code == 0 and last["mode"] == modes.OFFBOARD and abs(last["z"] + 10.0) < 0.3
    assert counters["lockstep_timeouts"] == 0 and counters["targets_received"] > 600
    assert not any(meta["drops"].get(k) for k in ("unsupported", "foreign_component", "out_of_range"))
