"""Shared fixtures of the end-to-end tests: the planned barrel roll, one reference flight."""
from __future__ import annotations

import json

import pytest

from tests.helpers.sitl import BARREL, CONTROLLER, VEHICLE, VEHICLE_IDEAL, load_record, mavreg, start_emulator


@pytest.fixture(scope="session")
def barrel_plan():
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.planning.plan_io import plan_file
    return plan_file(BARREL, load_vehicle(VEHICLE), load_controller(CONTROLLER))


def fly_lockstep(tmp, emulator_args=(), fly_args=(), during=None, vehicle=VEHICLE, world="ideal",
                 controller=CONTROLLER):
    """Emulator in lockstep + ``mavreg fly --vehicle`` as two processes; returns a result dict.

    ``vehicle`` is the parameter file both read: the emulator its physics, the daemon its
    design model (``mk_quadro_ideal.yaml``: ideal actuators on both sides). The paper's
    world and design by default: the emulator's ``ideal`` preset, ``paper_lqr.yaml``."""
    record = tmp / "groundtruth.npz"
    emu, url = start_emulator(record, "--lockstep", "--world", world, "--vehicle-params", str(vehicle),
                              *emulator_args)
    out = tmp / "out"
    try:
        fly = mavreg("fly", str(BARREL), "--vehicle", url, "--vehicle-lockstep", "--vehicle-params", str(vehicle),
                     "--controller", str(controller), "--out", str(out), "--timeout-s", "240", *fly_args)
        extra = during(fly, emu) if during is not None else None
        code = fly.wait(300)
    finally:
        emu_code = emu.stop()
    summary = json.loads((out / "summary.json").read_text())
    return {"code": code, "emu_code": emu_code, "summary": summary, "record": load_record(record),
            "out": out, "lines": fly.lines, "extra": extra}


@pytest.fixture(scope="session")
def ideal_flight(tmp_path_factory):
    """The barrel roll from the ground with ideal actuators (rotor time constant 0)."""
    return fly_lockstep(tmp_path_factory.mktemp("ideal"), ("--lockstep-timeout-s", "3"), vehicle=VEHICLE_IDEAL)
