"""Eq 34's one home: the mixer's kernel form (mavreg.model.mixer_kernel) against the numpy
reference (mavreg.model.mixer), and Mixer.from_vehicle against the vehicle file."""
import numpy as np
import pytest

from mavreg.config.vehicle import load_vehicle
from mavreg.config.paths import PARAMS_DIR
from mavreg.model import mixer_kernel as mk
from mavreg.model.mixer import Mixer, torques_first, yaw_then_lift

VEHICLE = load_vehicle(PARAMS_DIR / "vehicles/mk_quadro.yaml")
MIX = Mixer.from_vehicle(VEHICLE)


def test_from_vehicle_is_eq_34_of_the_vehicle_file():
    ref = Mixer(VEHICLE.arm_length_m, VEHICLE.drag_torque_ratio_m)
    assert np.array_equal(MIX.matrix, ref.matrix) and np.array_equal(MIX.inverse, ref.inverse)


@pytest.mark.parametrize("forces", [(1.0, 2.0, 3.0, 4.0), (9.5, 0.0, 0.3, 7.25), (2.0, 2.0, 2.0, 2.0)])
def test_wrench_kernel_is_the_mixer(forces):
    got = mk.wrench(VEHICLE.arm_length_m, VEHICLE.drag_torque_ratio_m, *forces)
    assert np.allclose(got, MIX.to_wrench(forces), rtol=0, atol=1e-12)
    # negative control: the rotor order matters (front, right, back, left)
    if len(set(forces)) > 1:
        swapped = mk.wrench(VEHICLE.arm_length_m, VEHICLE.drag_torque_ratio_m, *forces[::-1])
        assert not np.allclose(swapped, MIX.to_wrench(forces), atol=1e-6)


def test_allocation_kernels_are_the_policies():
    rng = np.random.default_rng(5)
    minv = np.ascontiguousarray(MIX.inverse).reshape(16)
    for _ in range(200):
        u = np.array([rng.uniform(0, 40), *rng.normal(0, 1.5, 2), rng.normal(0, 0.3)])
        f = np.empty(4)
        mk.yaw_then_lift(minv, u, 12.0, f)
        assert np.allclose(f, yaw_then_lift(MIX.inverse, u, 12.0), rtol=0, atol=1e-9)
        mk.torques_first(minv, u, 12.0, f)
        assert np.allclose(f, torques_first(MIX.inverse, u, 12.0), rtol=0, atol=1e-9)
