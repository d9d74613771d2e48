"""The plan cache keeps the gains, packed without loss, and rebuilds the rest bit for bit.

A plan served from the cache must fly exactly as the plan it was made from: every table of
the rebuilt plan equals the fresh one to the last bit, and a closed-loop flight on each gives
the same trajectory, bit for bit.
"""
from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver
from mavreg.config.vehicle import load_vehicle
from mavreg.planning.cache import PlanCache
from mavreg.planning.plan_io import plan_cached
from mavreg.maneuver.plan_entry import PlanEntry, decode_table, encode_table


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_table_round_trip_is_exact_on_awkward_values():
    rng = np.random.default_rng(3)
    smooth = np.cumsum(np.cumsum(rng.normal(size=(500, 4, 3)), axis=0), axis=0)
    awkward = np.array([0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324, -1.7976931348623157e308,
                        1.0, -1.0, 1e-300])
    smooth[:10, 0, 0] = awkward
    smooth[250:260, 3, 2] = awkward[::-1]
    for a in (smooth, smooth[:1], smooth[:2, 0], rng.normal(size=(7, 11))):
        back = decode_table(encode_table(a), a.shape)
        assert _same_bits(back, np.ascontiguousarray(a))


def test_a_packed_table_of_another_shape_is_refused():
    blob = encode_table(np.ones((10, 4)))
    with pytest.raises(ValueError):
        decode_table(blob, (10, 5))


@pytest.fixture(scope="module")
def fresh_and_cached(tmp_path_factory):
    vehicle = load_vehicle(DEFAULT_VEHICLE)
    controller = load_controller(PAPER_CONTROLLER)
    spec = load_maneuver(maneuver_file("barrel_roll"))
    cache = PlanCache(tmp_path_factory.mktemp("plans"))
    fresh = plan_cached(spec, vehicle, controller, cache=cache)
    cached = plan_cached(spec, vehicle, controller, cache=cache)
    assert (cache.misses, cache.hits) == (1, 1)
    return fresh, cached, cache


def test_cached_plan_equals_the_fresh_plan_bit_for_bit(fresh_and_cached):
    fresh, cached, _ = fresh_and_cached
    assert cached.from_cache and not fresh.from_cache        # the one field that says which is which
    for f in dataclasses.fields(fresh):
        if f.name == "from_cache":
            continue
        a, b = getattr(fresh, f.name), getattr(cached, f.name)
        if isinstance(a, np.ndarray):
            assert _same_bits(a, b), f.name
        elif f.name == "path":
            for name, value in vars(a).items():
                if isinstance(value, np.ndarray):
                    assert _same_bits(value, vars(b)[name]), f"path.{name}"
        else:
            assert a == b, f.name


def test_cache_entry_is_the_gains_not_the_plan(fresh_and_cached):
    fresh, _, cache = fresh_and_cached
    (entry_file,) = list(cache.directory.glob("*.plan.pickle"))
    with open(entry_file, "rb") as f:
        entry = pickle.load(f)
    assert isinstance(entry, PlanEntry)
    whole = len(pickle.dumps(fresh, protocol=pickle.HIGHEST_PROTOCOL))
    assert entry_file.stat().st_size < whole / 5          # about 2.6 of 20 MB
    assert entry_file.stat().st_size < fresh.K.nbytes / 2


def test_flight_on_the_cached_plan_is_the_same_flight(fresh_and_cached):
    """The whole barrel roll, 0.3 m off and with rotor noise, on the batch simulator."""
    from mavreg.sim.batch import BatchRun, fly_batch
    fresh, cached, _ = fresh_and_cached
    run = BatchRun(offset_m=(0.3, -0.3, 0.3), rotor_noise_sd_n=0.05, seed=7)
    a, b = (fly_batch(p, [run])[0] for p in (fresh, cached))
    assert a.status == b.status and len(a.x) > 10_000
    assert _same_bits(a.x, b.x) and _same_bits(a.rotor_applied_n, b.rotor_applied_n)


def test_a_damaged_entry_is_planned_again(fresh_and_cached, tmp_path):
    """An entry that unpickles but whose packed gains are damaged: planned again, the same plan."""
    fresh, _, cache = fresh_and_cached
    (entry_file,) = list(cache.directory.glob("*.plan.pickle"))
    with open(entry_file, "rb") as f:
        entry = pickle.load(f)
    damaged = dataclasses.replace(entry, gains=entry.gains[: len(entry.gains) // 2])
    other = PlanCache(tmp_path)
    other.directory.mkdir(parents=True, exist_ok=True)
    with open(other.directory / entry_file.name, "wb") as f:
        pickle.dump(damaged, f)
    vehicle = load_vehicle(DEFAULT_VEHICLE)
    controller = load_controller(PAPER_CONTROLLER)
    spec = load_maneuver(maneuver_file("barrel_roll"))
    again = plan_cached(spec, vehicle, controller, cache=other)
    assert other.hits == 1                       # the damaged entry was read ...
    assert _same_bits(again.K, fresh.K)          # ... and the plan made again
