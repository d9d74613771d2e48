"""The step kernel's vectors have one declared layout (mavreg.control.controllers.step_kernel): slots do
not overlap, the governor's block is contiguous in the order the kernel reads it, and the one
packer (fastpath.step_params) puts each value in its slot."""
import numpy as np

from mavreg.control.controllers import step_kernel as sk
from mavreg.control.controllers.fastpath import step_params

FIELDS = {"P_LEAD": 1, "P_DECAY": 1, "P_FMAX": 1, "P_WINDOW": 1, "P_MARGIN": 1, "P_MAX_TURN": 1,
          "P_CXY": 1, "P_CZ": 1, "P_TORQUES_FIRST": 1, "P_AUGMENTED": 1, "P_END": 1, "P_NK": 1,
          "P_SO3": 1, "P_GOV": 1, "P_GOV_COL": 1, "P_MASS": 1, "P_PARASITIC": 1, "P_GOV_ACCEL": 1,
          "P_GOV_TAU": 1, "P_GOV_BAND": 1, "P_GOV_GAIN": 1, "P_GOV_MAX_ACCEL": 1, "P_GOV_CAPPED": 1,
          "P_GOV_DT": 1, "P_GOV_OMEGA": 1, "P_GOV_JERK": 1, "P_MINV": 16, "P_MIX": 16}


def test_parameter_slots_tile_the_vector():
    declared = {name for name in dir(sk) if name.startswith("P_")}
    assert declared == set(FIELDS)
    used = np.zeros(sk.N_PARAMS, dtype=int)
    for name, width in FIELDS.items():
        first = getattr(sk, name)
        used[first:first + width] += 1
    assert np.all(used == 1)
    assert sk.P_GOV_JERK - sk.P_GOV_ACCEL == 8


def test_state_and_output_slots():
    assert (sk.ST_S, sk.ST_HAS_EST, sk.ST_EST, sk.ST_GOV, sk.ST_WIDTH) == (0, 1, 2, 6, 11)
    assert (sk.OUT_S, sk.OUT_W, sk.OUT_U, sk.OUT_ROTORS, sk.OUT_WIDTH) == (0, 1, 12, 16, 20)
    assert (sk.TABLE_X, sk.TABLE_U, sk.TABLE_V, sk.TABLE_K) == (0, 12, 16, 17)


def test_the_packer_fills_each_slot():
    M, Minv = np.arange(16.0).reshape(4, 4), -np.arange(16.0).reshape(4, 4)
    gp = tuple(100.0 + i for i in range(9))
    prm = step_params(M, Minv, 7.0, True, 0.021, 0.6, (0.4, 0.7), 0.5, 0.3, 0.2, n_k=15, so3=True,
                      end_m=40.0, governor=(61, 0.749, 0.01, gp))
    expect = {"P_LEAD": 0.021, "P_DECAY": 0.6, "P_FMAX": 7.0, "P_WINDOW": 0.3, "P_MARGIN": 0.2,
              "P_MAX_TURN": 0.5, "P_CXY": 0.4, "P_CZ": 0.7, "P_TORQUES_FIRST": 1.0, "P_AUGMENTED": 1.0,
              "P_END": 40.0, "P_NK": 15, "P_SO3": 1.0, "P_GOV": 1.0, "P_GOV_COL": 61, "P_MASS": 0.749,
              "P_PARASITIC": 0.01}
    for name, value in expect.items():
        assert prm[getattr(sk, name)] == value, name
    assert tuple(prm[sk.P_GOV_ACCEL:sk.P_GOV_JERK + 1]) == gp
    assert np.array_equal(prm[sk.P_MIX:sk.P_MIX + 16], M.reshape(16))
    assert np.array_equal(prm[sk.P_MINV:sk.P_MINV + 16], Minv.reshape(16))
    assert step_params(M, Minv)[sk.P_GOV] == 0.0
