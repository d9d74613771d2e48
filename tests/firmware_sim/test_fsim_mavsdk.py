"""MAVSDK-Python (the native binding, ``pip install 'mavsdk>=4,<5'``, in the ``test`` extra)
drives firmware_sim as it would drive a PX4 vehicle: connect, telemetry (health, landed state,
battery, home), parameters, arm, take-off, hold, land and the automatic disarm.

Real time (MAVSDK has its own threads and clocks) in the default realistic world, about 12 s;
every wait is bounded and judged on what the vehicle reports, never on how long it took.
Skipped with a message where mavsdk is not installed."""
from __future__ import annotations

import time

import pytest

mavsdk = pytest.importorskip("mavsdk", minversion="4", reason="MAVSDK-Python >= 4 is not installed: "
                             "pip install 'mavsdk>=4,<5' (in the test extra) to run this test")

from mavsdk import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.plugins.action import Action  # noqa: E402
from mavsdk.plugins.param import Param  # noqa: E402
from mavsdk.plugins.telemetry import FlightMode, LandedState, Telemetry  # noqa: E402

from tests.helpers.emulator import Emulator  # noqa: E402


def _until(pred, timeout_s: float, what: str):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        value = pred()
        if value:
            return value
        time.sleep(0.02)
    raise AssertionError(f"MAVSDK did not see {what} within {timeout_s} s")


def _call(fn, tel):
    """``fn()``; on a refusal, the vehicle's last STATUSTEXT says why."""
    try:
        return fn()
    except mavsdk.MavsdkError as exc:
        raise AssertionError(f"{exc}; vehicle says: {tel.status_text().text!r}") from None


@pytest.mark.slow          # 12 s real time; before each release (the messages and commands it needs: test_fsim_px4.py)
def test_mavsdk_connects_reads_telemetry_takes_off_lands_and_disarms():
    with Emulator("--peer-system-id", "245", "--control-rate-hz", "250") as em:
        sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        try:
            assert sdk.add_any_connection(f"udpout://127.0.0.1:{em.port}") == mavsdk.ConnectionResult.SUCCESS
            system = sdk.first_autopilot(10.0)
            assert system is not None, "no autopilot discovered"
            tel, action, param = Telemetry(system), Action(system), Param(system)
            _until(tel.health_all_ok, 10.0, "health all ok")
            h = tel.health()
            assert h.is_local_position_ok and h.is_global_position_ok and h.is_home_position_ok and h.is_armable
            # SYS_STATUS (health) and EXTENDED_SYS_STATE are separate streams: either may come first
            _until(lambda: tel.landed_state() == LandedState.ON_GROUND, 5.0, "landed state on the ground")
            battery = _until(lambda: tel.battery() if tel.battery().voltage_v > 0 else None, 5.0, "battery")
            assert 16.0 < battery.voltage_v <= 16.8 and battery.remaining_percent > 99.0
            home = tel.home()
            assert home.latitude_deg == pytest.approx(47.397742) and home.absolute_altitude_m == pytest.approx(488.0)
            assert param.get_param_float("COM_OF_LOSS_T") == pytest.approx(0.25)
            action.set_takeoff_altitude(3.0)                       # PARAM_SET of MIS_TAKEOFF_ALT
            assert action.get_takeoff_altitude() == pytest.approx(3.0)

            seen: list = []

            def note():
                s = tel.landed_state()
                if not seen or seen[-1] != s:
                    seen.append(s)

            action.arm()
            _until(tel.armed, 5.0, "armed")
            _call(action.takeoff, tel)
            _until(lambda: note() or (tel.flight_mode() == FlightMode.HOLD
                                      and tel.position().relative_altitude_m > 2.7), 20.0, "HOLD at 3 m")
            _until(lambda: note() or tel.landed_state() == LandedState.IN_AIR, 5.0, "in air")
            assert tel.position().relative_altitude_m == pytest.approx(3.0, abs=0.3)
            action.land()
            _until(lambda: note() or not tel.armed(), 20.0, "disarmed after landing")
            _until(lambda: note() or tel.landed_state() == LandedState.ON_GROUND, 5.0, "on the ground")
            assert [s for s in seen if s != LandedState.UNKNOWN] == [
                LandedState.ON_GROUND, LandedState.TAKING_OFF, LandedState.IN_AIR,
                LandedState.LANDING, LandedState.ON_GROUND]
            assert abs(tel.position().relative_altitude_m) < 0.2
        finally:
            sdk.destroy()
        assert em.stop() == 0


@pytest.mark.slow     # 18 s in real time; run before releases (README)
def test_mavsdk_offboard_position_example():
    """MAVSDK's offboard_position_ned example, its set-points and calls unchanged, each leg
    waited for until reached (the example sleeps 10-15 s a leg), then landed at 2 m/s
    (``MPC_LAND_SPEED`` set through MAVSDK's Param plugin). About 20 s."""
    from mavsdk.plugins.offboard import Offboard, PositionNedYaw

    with Emulator("--peer-system-id", "245", "--control-rate-hz", "250") as em:
        sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        try:
            sdk.add_any_connection(f"udpout://127.0.0.1:{em.port}")
            system = sdk.first_autopilot(10.0)
            tel, action, offboard = Telemetry(system), Action(system), Offboard(system)
            _until(lambda: tel.health().is_global_position_ok and tel.health().is_home_position_ok,
                   10.0, "global position and home ok")
            action.arm()
            offboard.set_position_ned(PositionNedYaw(0.0, 0.0, 0.0, 0.0))
            offboard.start()
            assert tel.flight_mode() in (FlightMode.OFFBOARD, FlightMode.HOLD)   # the heartbeat may lag
            for n, e, d, yaw in ((0.0, 0.0, -5.0, 0.0), (5.0, 0.0, -5.0, 90.0), (5.0, 10.0, -5.0, 90.0),
                                 (0.0, 10.0, -5.0, 0.0)):
                offboard.set_position_ned(PositionNedYaw(n, e, d, yaw))

                def there(n=n, e=e, d=d, yaw=yaw):
                    p = tel.position_velocity_ned().position
                    heading = (tel.attitude_euler().yaw_deg - yaw + 180.0) % 360.0 - 180.0
                    return (abs(p.north_m - n) < 0.3 and abs(p.east_m - e) < 0.3 and abs(p.down_m - d) < 0.3
                            and abs(heading) < 5.0)
                _until(there, 15.0, f"set-point {(n, e, d, yaw)}")
                assert tel.flight_mode() == FlightMode.OFFBOARD
            offboard.stop()
            _until(lambda: tel.flight_mode() == FlightMode.HOLD, 5.0, "HOLD after offboard stop")
            Param(system).set_param_float("MPC_LAND_SPEED", 2.0)      # descend faster (PX4's parameter)
            action.land()
            _until(lambda: not tel.armed(), 10.0, "disarmed after landing")
        finally:
            sdk.destroy()
        assert em.stop() == 0
