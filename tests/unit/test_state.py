"""State assembly: equal time_boot_ms only, quaternion preferred, Euler refused near vertical."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.flight.state import StateAssembler
from mavreg.model.rotation import rpy_to_matrix
from tests.helpers.supervisor_harness import att_e, att_q, pos


def test_complete_only_with_equal_time():
    a = StateAssembler()
    assert a.add(att_q(10)) is None
    assert a.add(pos(12)) is None          # different time: no sample
    assert a.add(att_q(12)) is not None    # now both at 12
    assert a.counters.unmatched >= 1


def test_mixed_time_never_used_under_reordering():
    a = StateAssembler()
    seq = [att_q(10, (0.1, 0, 0)), pos(12, (1, 0, 0)), pos(10, (9, 9, 9)), att_q(12, (0.2, 0, 0))]
    samples = [s for s in (a.add(m) for m in seq) if s is not None]
    # each sample pairs parts of one time only, whatever the arrival order
    assert [s.time_boot_ms for s in samples] == [10, 12]
    assert samples[0].x[0] == pytest.approx(9.0) and samples[0].x[3] == pytest.approx(0.1)
    assert samples[1].x[0] == pytest.approx(1.0) and samples[1].x[3] == pytest.approx(0.2)


def test_unmatched_parts_are_discarded_when_a_newer_time_completes():
    a = StateAssembler()
    for m in [att_q(2), pos(4), att_q(6), pos(8), att_q(8)]:
        s = a.add(m)
    assert s.time_boot_ms == 8 and a.counters.unmatched == 3
    assert a.add(pos(6)) is None and a.add(pos(2)) is None  # older than the last sample: late


def test_late_parts_dropped():
    a = StateAssembler()
    a.add(att_q(20)); a.add(pos(20))
    assert a.add(pos(18)) is None and a.add(att_q(18)) is None
    assert a.counters.late == 2


@settings(max_examples=60, deadline=None)
@given(rpy=st.tuples(st.floats(-3.1, 3.1), st.floats(-1.4, 1.4), st.floats(-3.1, 3.1)),
       v=st.tuples(*[st.floats(-10, 10)] * 3))
def test_body_velocity_is_rt_v_ned(rpy, v):
    a = StateAssembler()
    a.add(att_q(5, rpy, (0.1, 0.2, 0.3)))
    s = a.add(pos(5, (1, 2, -3), v))
    R = rpy_to_matrix(*rpy)
    np.testing.assert_allclose(s.x[6:9], R.T @ np.array(v), atol=1e-4)
    np.testing.assert_allclose(s.velocity_ned_m_s, v, atol=1e-4)
    np.testing.assert_allclose(s.x[9:12], (0.1, 0.2, 0.3), atol=1e-6)
    assert s.from_quaternion


def test_euler_used_without_quaternion_and_refused_near_vertical():
    a = StateAssembler()
    a.add(att_e(5, (0.1, 0.2, 0.3)))
    s = a.add(pos(5))
    assert s is not None and not s.from_quaternion
    np.testing.assert_allclose(s.x[3:6], (0.1, 0.2, 0.3), atol=1e-6)
    assert a.add(att_e(6, (0.0, np.deg2rad(85.0), 0.0))) is None
    assert a.add(pos(6)) is None
    assert a.counters.euler_near_vertical == 1


def test_quaternion_flies_through_vertical_and_euler_is_then_ignored():
    a = StateAssembler()
    a.add(att_q(5, (0.0, np.deg2rad(89.0), 0.0)))
    assert a.add(pos(5)) is not None
    assert a.add(att_e(6)) is None and a.counters.euler_ignored == 1


def test_non_finite_parts_refused():
    a = StateAssembler()
    assert a.add(pos(5, (np.nan, 0, 0))) is None
    a.add(att_q(5))
    assert a.counters.non_finite == 1


def test_scalar_assembly_agrees_with_the_numpy_rotation_functions():
    """The assembler's scalar formulas against mavreg.model.rotation (the reference path)."""
    from mavreg.model.rotation import matrix_to_rpy, quat_to_matrix, rpy_to_matrix
    rng = np.random.default_rng(3)
    asm_q, asm_e = StateAssembler(), StateAssembler(euler_pitch_limit_rad=np.pi)
    for k in range(1, 400):
        q = rng.standard_normal(4)
        q *= rng.uniform(0.6, 2.0) / np.linalg.norm(q)              # not unit: the assembler normalizes
        rates, p, v = rng.uniform(-5, 5, 3), rng.uniform(-50, 50, 3), rng.uniform(-10, 10, 3)
        rpy = rng.uniform(-np.pi, np.pi, 3) * (1.0, 0.45, 1.0)
        lpn = mavlink2.MAVLink_local_position_ned_message(k, *p, *v)
        aq = mavlink2.MAVLink_attitude_quaternion_message(k, *q, *rates, [0, 0, 0, 0])
        att = mavlink2.MAVLink_attitude_message(k, *rpy, *rates)
        assert asm_q.add(lpn) is None
        sq = asm_q.add(aq)
        assert asm_e.add(att) is None
        se = asm_e.add(lpn)
        for sample, R in ((sq, quat_to_matrix(q)), (se, rpy_to_matrix(*rpy))):
            x = np.concatenate([p, matrix_to_rpy(R), R.T @ v, rates])
            np.testing.assert_allclose(sample.rotation, R, rtol=0, atol=1e-14)
            np.testing.assert_allclose(sample.x, x, rtol=1e-13, atol=1e-12)
            assert sample.x.dtype == float and sample.x.shape == (12,) and sample.rotation.shape == (3, 3)
