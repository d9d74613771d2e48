"""The health gate on synthetic holds, and the plan-in-envelope check."""
from __future__ import annotations

import math

import numpy as np

from mavreg.config.envelope import EnvelopeParams
from mavreg.daemon.flight.gate import HealthGate, nominal_points, plan_outside_envelope

MASS, FMAX, G = 0.749, 12.0, 9.81
HOVER_N = MASS * G / 4


def hold(gate, seconds=1.2, pos=0.002, att=math.radians(0.2), rotors=None, rate_hz=500, seed=0):
    """Feed a hold: small errors, rotor commands around hover with 0.1 N of noise."""
    rng = np.random.default_rng(seed)
    n = int(seconds * rate_hz)
    for k in range(n):
        f = np.full(4, HOVER_N) + rng.normal(0, 0.1, 4) if rotors is None else rotors(k)
        gate.observe(k / rate_hz, pos, att, f)
    return gate


def gate(link=None, **env):
    return HealthGate(EnvelopeParams(**env), MASS, FMAX, link)


def test_clean_hold_passes_and_needs_a_full_window():
    g = gate()
    hold(g, seconds=0.5)
    assert not g.ready()
    hold(g, seconds=1.2)
    assert g.ready() and g.evaluate().ok


def test_estimator_noise_passes():
    """0.15 N of white noise on each rotor (what 5 mm / 2 cm/s / 0.3 deg of estimate noise
    makes the hover LQR do) is under the chatter bound with margin."""
    g = gate()
    rng = np.random.default_rng(3)
    hold(g, rotors=lambda k: np.full(4, HOVER_N) + rng.normal(0, 0.15, 4))
    assert g.evaluate().ok


def test_heavier_vehicle_is_refused_by_thrust():
    v = hold(gate(), rotors=lambda k: np.full(4, 1.4 * HOVER_N)).evaluate()
    assert not v.ok and v.bound == "gate_thrust" and abs(v.value - 1.4) < 1e-9 and v.limit == 1.2
    assert hold(gate(), rotors=lambda k: np.full(4, 1.15 * HOVER_N)).evaluate().ok


def test_chatter_and_clipping_are_refused():
    v = hold(gate(), rotors=lambda k: np.full(4, HOVER_N) + (1.0 if k % 2 else -1.0) * np.array([1, 0, -1, 0])).evaluate()
    assert not v.ok and v.bound == "gate_rotor_chatter"
    v = hold(gate(), rotors=lambda k: np.array([FMAX + 0.5, HOVER_N, 0.0, HOVER_N]) if k == 300
             else np.full(4, HOVER_N)).evaluate()
    assert not v.ok and v.bound == "gate_saturation"


def test_tracking_is_judged():
    assert hold(gate(), pos=0.2).evaluate().bound == "gate_position"
    assert hold(gate(), att=math.radians(6)).evaluate().bound == "gate_attitude"


def test_link_bounds_and_unknown_link():
    assert hold(gate(link=lambda: None)).evaluate().ok
    assert hold(gate(link=lambda: (0.012, 0.003))).evaluate().ok          # the realistic world
    v = hold(gate(link=lambda: (0.08, 0.001))).evaluate()
    assert not v.ok and v.bound == "gate_link_delay" and v.value == 0.08
    v = hold(gate(link=lambda: (0.02, 0.03))).evaluate()
    assert not v.ok and v.bound == "gate_link_jitter"


class _Line:
    """A straight plan from ``start`` along ``direction``."""

    def __init__(self, start, direction, length_m):
        self.start = np.asarray(start, float)
        self.direction = np.asarray(direction, float) / np.linalg.norm(direction)
        self.length_m = length_m

    def nominal_state(self, s):
        x = np.zeros(12)
        x[:3] = self.start + s * self.direction
        return x


def test_plan_inside_the_envelope_from_the_take_off_point():
    env = EnvelopeParams()
    level = nominal_points(_Line((0, 0, -3), (1, 0, 0), 20))
    assert plan_outside_envelope(level, (0, 0, 0), env) is None
    v = plan_outside_envelope(nominal_points(_Line((0, 0, -3), (1, 0, 0.2), 20)), (0, 0, 0), env)
    assert v.bound == "gate_plan_floor" and v.value < 1.0
    # the same plan seen from a take-off point 2.5 m lower: 5.5 m up, fine; from 40 m
    # south, it leaves the 50 m box
    assert plan_outside_envelope(level, (0, 0, 2.5), env) is None
    v = plan_outside_envelope(level, (-40, 0, 0), env)
    assert v.bound == "gate_plan_geofence" and v.value == 60.0
