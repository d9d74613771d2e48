"""What each flight of a campaign through one ``mavreg serve`` flies, drawn from one seed.

Two campaigns (docs/reliability.md, "Days, not minutes"):

- **soak**: one emulator, never restarted, the bundled airframe in the ideal world; flight
  after flight of library maneuvers, laps and a short hop, with a rejected upload now and
  then. What it measures is the daemon over time: memory, descriptors, threads, latency.
- **chaos**: every five flights a world of their own, into which the emulator restarts (a
  vehicle reboot between flights, as the daemon sees it): link faults (loss, bursts,
  reordering, outages), gusts, an airframe drawn around the vehicle file; and per flight, the
  host loaded on every core, and hostile uploads before the flight's own.

Pure: a seed in, a list of :class:`FlightDraw` out (no processes, no files).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["KINDS", "FlightDraw", "draw_flights", "HOP_YAML", "HOSTILE_UPLOADS"]

KINDS = ("soak", "chaos")

HOP_YAML = """\
kind: maneuver
version: 1
name: hop
description: a 4 m line north at up to 1.5 m/s, 1.5 m up (the campaigns' short flight)
start: {position_m: [0.5, 0.0, -1.5], heading_deg: 0, climb_deg: 0}
segments:
  - {name: line, line: {length_m: 4.0}}
speed:
  initial_m_s: 0.5
  changes:
    - {segment: line, offset_m: 0.0, length_m: 1.5, to_m_s: 1.5}
    - {segment: line, anchor: end, offset_m: 1.5, length_m: 1.5, to_m_s: 0.5}
yaw: {initial_deg: 0}
"""
"""The short flight most campaign flights fly (take-off, 4 m, landing: about 25 s of vehicle time)."""

HOSTILE_UPLOADS = {
    "unknown_key": HOP_YAML + "colour: red\n",
    "missing_version": HOP_YAML.replace("version: 1\n", ""),
    "wrong_type": HOP_YAML.replace("length_m: 4.0", "length_m: four"),
    "negative_speed": HOP_YAML.replace("initial_m_s: 0.5", "initial_m_s: -3"),
    "huge_length": HOP_YAML.replace("length_m: 4.0", "length_m: 1.0e+300"),
    "not_finite": HOP_YAML.replace("length_m: 4.0", "length_m: .nan"),
    "too_fast": HOP_YAML.replace("to_m_s: 1.5", "to_m_s: 90.0"),
    "alias_bomb": "kind: maneuver\na: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a]\n"
                  "c: &c [*b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c]\n"
                  "e: [*d, *d, *d, *d, *d, *d, *d, *d]\n",
    "binary": "\x00\x01\x02kind: maneuver\xff",
    "not_a_mapping": "- just\n- a list\n",
    "deep": "kind: maneuver\nversion: 1\nname: " + "[" * 5000 + "]" * 5000 + "\n",
    "empty": "",
}
"""Uploads every one of which ``serve`` must reject in one line, changing nothing."""

SOAK_MANEUVERS = (("hop", None, 0.7), ("slalom", None, 0.1), ("figure_eight", None, 0.05),
                  ("barrel_roll", None, 0.1), ("barrel_roll", 2, 0.05))
"""(maneuver, laps, probability) of a soak flight: the hop, library maneuvers, and laps."""
WORLD_FLIGHTS = 5
"""Chaos: a world (link faults, gust, airframe) is drawn for this many flights in a row; the
emulator restarts into each new one (a vehicle reboot between flights)."""
CHAOS_MANEUVERS = (("hop", None, 0.75), ("slalom", None, 0.08), ("figure_eight", None, 0.07),
                   ("barrel_roll", None, 0.1))


@dataclass(frozen=True)
class FlightDraw:
    """One flight of a campaign."""

    number: int
    maneuver: str
    """A library maneuver's name, or ``hop`` (:data:`HOP_YAML`)."""
    laps: int | None
    hostile: tuple[str, ...]
    """Keys of :data:`HOSTILE_UPLOADS` sent before the flight's own upload."""
    world: tuple[str, ...]
    """The emulator's flags for this flight (chaos); empty: the soak's one emulator."""
    load: bool
    """Every core is kept busy from the upload to the flight's end."""
    restart: bool
    """The emulator restarts (a reboot between flights) before this flight."""

    def describe(self) -> str:
        parts = [self.maneuver + (f" x{self.laps}" if self.laps else "")]
        if self.world:
            parts.append(" ".join(self.world))
        if self.load:
            parts.append("host loaded")
        if self.hostile:
            parts.append("hostile: " + ",".join(self.hostile))
        return "; ".join(parts)


def _pick(rng, table):
    probs = np.array([p for *_, p in table], dtype=float)
    name, laps, _ = table[int(rng.choice(len(table), p=probs / probs.sum()))]
    return name, laps


def _link_faults(rng) -> tuple[str, ...]:
    """Drawn link faults: none, loss, bursts, reordering or an outage (one kind a flight)."""
    kind = rng.choice(["none", "loss", "bursts", "reorder", "outage"], p=[0.3, 0.2, 0.2, 0.15, 0.15])
    if kind == "loss":
        return (f"--link-faults=loss={rng.uniform(0.01, 0.05):.3f}",)
    if kind == "bursts":
        return (f"--link-faults=loss=0.01,burst_enter={rng.uniform(0.005, 0.02):.3f},burst_exit=0.25",)
    if kind == "reorder":
        return (f"--link-faults=reorder={rng.uniform(0.01, 0.05):.3f},reorder_s=0.01,jitter_s=0.003",)
    if kind == "outage":    # telemetry outages at sim times over the world's flights (about 40 s each)
        starts = np.sort(rng.uniform(8.0, 40.0 * WORLD_FLIGHTS, size=WORLD_FLIGHTS))
        return ("--downlink-faults=" + ",".join(f"outage={t:.1f}:{rng.uniform(0.05, 0.3):.2f}" for t in starts),)
    return ()


def _gust(rng) -> tuple[str, ...]:
    if rng.random() < 0.5:
        return ()
    speed, from_deg = rng.uniform(1.0, 4.0), rng.uniform(0.0, 360.0)
    return (f"--wind-speed-m-s={speed:.1f}", f"--wind-from-deg={from_deg:.0f}")


def _chaos_world(rng, seed: int) -> tuple[str, ...]:
    world = ("--world=realistic", f"--seed={seed}")
    if rng.random() < 0.5:
        world += (f"--mismatch-seed={seed}",)
    return world + _link_faults(rng) + _gust(rng)


def draw_flights(kind: str, seed: int, flights: int) -> list[FlightDraw]:
    """The campaign ``kind`` (:data:`KINDS`) of ``flights`` flights drawn from ``seed``.

    Examples
    --------
    >>> a = draw_flights("chaos", 7, 6)
    >>> a == draw_flights("chaos", 7, 6), [f.restart for f in a]
    (True, [True, False, False, False, False, True])
    >>> [f.world for f in draw_flights("soak", 0, 2)]
    [(), ()]
    """
    if kind not in KINDS:
        raise ValueError(f"campaign {kind!r}: expected one of {', '.join(KINDS)}")
    if flights < 1:
        raise ValueError(f"a campaign flies at least one flight, got {flights}")
    rng = np.random.default_rng(seed)
    hostile_names = sorted(HOSTILE_UPLOADS)
    out = []
    for n in range(1, flights + 1):
        if kind == "soak":
            name, laps = _pick(rng, SOAK_MANEUVERS)
            hostile = (hostile_names[int(rng.integers(len(hostile_names)))],) if n % 5 == 0 else ()
            out.append(FlightDraw(n, name, laps, hostile, (), False, False))
            continue
        name, laps = _pick(rng, CHAOS_MANEUVERS)
        k = int(rng.choice([0, 1, 2], p=[0.6, 0.3, 0.1]))
        hostile = tuple(hostile_names[int(i)] for i in rng.choice(len(hostile_names), size=k, replace=False))
        restart = (n - 1) % WORLD_FLIGHTS == 0
        if restart:
            world = _chaos_world(rng, int(rng.integers(1 << 31)))
        out.append(FlightDraw(n, name, laps, hostile, world, bool(rng.random() < 0.2), restart))
    return out
