"""Seeded airframe mismatch: the true airframe drawn around the vehicle file.

``firmware-sim --mismatch-seed N`` flies a vehicle that is *not* its file: the mass, the
principal moments of inertia, each rotor's thrust constant, the rotors' yaw-torque
coefficient, the arm length, the motor time constant and the centre of mass are drawn
once, at start-up, from a generator seeded by ``N`` alone (independent of ``--seed``,
which keeps seeding the rotor noise and the world's streams). The offboard controller
designs on the file; the physics flies the draw.

Distributions (``X`` = ``--mismatch-scale``, 1 by default; ``u`` uniform in [0, 1)):

==========================  ==============================  ==========================================
parameter                   nominal (vehicle file)          true value
==========================  ==============================  ==========================================
mass                        ``mass_kg``                     nominal (1 + X e), e ~ U(-0.15, 0.15)
each principal moment       ``inertia_kg_m2[i]``            nominal (1 + X e_i), e_i ~ U(-0.3, 0.3)
rotor i thrust constant     1 (per newton commanded)        1 + X e_i, e_i ~ U(-0.1, 0.1)
yaw-torque coefficient      ``drag_torque_ratio_m``         nominal (1 + X e), e ~ U(-0.3, 0.3)
arm length                  ``arm_length_m``                nominal (1 + X e), e ~ U(-0.05, 0.05)
rotor time constant         the true rotor lag              nominal + X (t - nominal), t ~ U(10, 50) ms
centre-of-mass offset       0                               X r (cos a, sin a, 0), r = 1 cm sqrt(u),
                                                            a ~ U(0, 2 pi): uniform on a 1 cm disc
==========================  ==============================  ==========================================

All errors are independent. The draw itself does not depend on ``X``: a smaller scale
moves the same airframe towards the file. An explicit flag (``--mass-kg``,
``--inertia-kg-m2``, ``--inertia-scale``, ``--inertia-perturb-sd-kg-m2``,
``--rotor-time-constant-s``) wins over the draw for its parameter; the other parameters
keep their draws (every draw is always made, in a fixed order).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .physics import inertia_matrix

__all__ = ["MismatchBounds", "BOUNDS", "MismatchDraw", "draw_mismatch", "apply_mismatch",
           "airframe_arrays", "airframe_meta", "describe_airframe", "MISMATCH_STREAM_KEY", "KEEPABLE"]

MISMATCH_STREAM_KEY = 18
"""Spawn key of the mismatch generator's seed sequence (issue 18): the stream
``SeedSequence(N, spawn_key=(18,))`` differs from every ``default_rng(seed)`` and
``default_rng([seed, i])`` stream the emulator draws noise from, for any N."""

KEEPABLE = ("mass_kg", "inertia_kg_m2", "rotor_time_constant_s")
"""Parameters an explicit command-line flag can keep from the draw."""


@dataclass(frozen=True)
class MismatchBounds:
    """Half-widths of the relative errors (``true = nominal (1 + e)``, ``|e| <= bound``),
    the interval of the rotor time constant and the radius of the centre-of-mass disc."""

    mass_rel: float = 0.15
    inertia_rel: float = 0.30
    rotor_gain_rel: float = 0.10
    drag_torque_ratio_rel: float = 0.30
    arm_length_rel: float = 0.05
    rotor_time_constant_min_s: float = 0.010
    rotor_time_constant_max_s: float = 0.050
    com_offset_max_m: float = 0.010


BOUNDS = MismatchBounds()
"""The documented bounds (docs/firmware_sim.md, "Airframe mismatch")."""


@dataclass(frozen=True)
class MismatchDraw:
    """One draw at full scale, and the scale it is applied with.

    Attributes
    ----------
    seed : int
        ``--mismatch-seed``.
    scale : float
        ``--mismatch-scale`` in (0, 1]: every deviation from the file is multiplied by it.
    mass_rel, drag_torque_ratio_rel, arm_length_rel : float
        Relative errors ``e`` (true = nominal (1 + scale e)).
    inertia_rel : tuple of 3 floats
        Relative errors of the principal moments (x, y, z).
    rotor_gain_rel : tuple of 4 floats
        Relative errors of the rotors' thrust constants (rotors 1..4: front, right, back, left).
    rotor_time_constant_s : float
        The drawn motor time constant (true = nominal + scale (drawn - nominal)).
    com_offset_m : tuple of 3 floats
        The drawn centre-of-mass offset in the body frame (FRD); z is 0.
    """

    seed: int
    scale: float
    mass_rel: float
    inertia_rel: tuple
    rotor_gain_rel: tuple
    drag_torque_ratio_rel: float
    arm_length_rel: float
    rotor_time_constant_s: float
    com_offset_m: tuple


def draw_mismatch(seed: int, scale: float = 1.0, bounds: MismatchBounds = BOUNDS) -> MismatchDraw:
    """Draw the airframe errors of ``--mismatch-seed seed``.

    Thirteen uniform numbers from ``numpy.random.default_rng(SeedSequence(seed,
    spawn_key=(18,)))``, in this order: mass, moments x, y, z, rotors 1..4, yaw
    coefficient, arm length, time constant, offset radius, offset angle.

    Raises
    ------
    ValueError
        One line: a seed that is not an integer >= 0, or a scale outside (0, 1].
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"--mismatch-seed must be an integer >= 0, got {seed!r}")
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and 0.0 < scale <= 1.0):
        raise ValueError(f"--mismatch-scale must be a number in (0, 1], got {scale!r}")
    ss = np.random.SeedSequence(int(seed), spawn_key=(MISMATCH_STREAM_KEY,))
    u = np.random.default_rng(ss).random(13).tolist()
    b = bounds

    def sym(x: float, half: float) -> float:
        return half * (2.0 * x - 1.0)

    radius = b.com_offset_max_m * math.sqrt(u[11])
    angle = 2.0 * math.pi * u[12]
    return MismatchDraw(
        seed=int(seed), scale=float(scale), mass_rel=sym(u[0], b.mass_rel),
        inertia_rel=tuple(sym(x, b.inertia_rel) for x in u[1:4]),
        rotor_gain_rel=tuple(sym(x, b.rotor_gain_rel) for x in u[4:8]),
        drag_torque_ratio_rel=sym(u[8], b.drag_torque_ratio_rel),
        arm_length_rel=sym(u[9], b.arm_length_rel),
        rotor_time_constant_s=b.rotor_time_constant_min_s
        + (b.rotor_time_constant_max_s - b.rotor_time_constant_min_s) * u[10],
        com_offset_m=(radius * math.cos(angle), radius * math.sin(angle), 0.0))


def apply_mismatch(params, draw: MismatchDraw | None, kept=()):
    """The true airframe: ``params`` (a :class:`firmware_sim.params.SimParams` resolved from
    the file and the flags) with ``draw`` applied, except for the parameters in ``kept``.

    Parameters
    ----------
    params : SimParams
        Without mismatch (``rotor_gain`` and ``com_offset_m`` nominal).
    draw : MismatchDraw or None
        ``None`` returns ``params`` itself.
    kept : iterable of str
        Names from :data:`KEEPABLE` set by an explicit flag: they keep ``params``' value.

    Raises
    ------
    ValueError
        One line: the drawn vehicle cannot hover, or its inertia matrix (drawn diagonal,
        the file's products of inertia) is not positive definite.
    """
    if draw is None:
        return params
    kept = tuple(sorted(set(kept)))
    unknown = set(kept) - set(KEEPABLE)
    if unknown:
        raise ValueError(f"cannot keep {sorted(unknown)} from the mismatch draw")
    x = draw.scale
    v = params.vehicle
    emu = v.emulator
    changes = {"arm_length_m": v.arm_length_m * (1.0 + x * draw.arm_length_rel),
               "drag_torque_ratio_m": v.drag_torque_ratio_m * (1.0 + x * draw.drag_torque_ratio_rel)}
    if "mass_kg" not in kept:
        changes["mass_kg"] = v.mass_kg * (1.0 + x * draw.mass_rel)
    if "rotor_time_constant_s" not in kept:
        tau = v.true_rotor_time_constant_s
        changes["emulator"] = dataclasses.replace(
            emu, true_rotor_time_constant_s=tau + x * (draw.rotor_time_constant_s - tau))
    J = params.inertia_matrix_kg_m2
    if "inertia_kg_m2" not in kept:
        diag = tuple(J[i][i] * (1.0 + x * draw.inertia_rel[i]) for i in range(3))
        J = inertia_matrix(diag, (J[0][1], J[0][2], J[1][2]))
    try:
        vehicle = dataclasses.replace(v, **changes)      # re-runs the hover check
    except ValueError as exc:
        raise ValueError(f"--mismatch-seed {draw.seed}: {exc}") from None
    return dataclasses.replace(
        params, vehicle=vehicle, inertia_matrix_kg_m2=J,
        rotor_gain=tuple(1.0 + x * e for e in draw.rotor_gain_rel),
        com_offset_m=tuple(x * c for c in draw.com_offset_m), mismatch=draw, mismatch_kept=kept)


def airframe_arrays(params) -> dict:
    """The true airframe of ``params`` as the recording's numeric ``airframe_*`` fields.

    Written with or without a mismatch (then the file's values and the flags'); see
    docs/firmware_sim.md, "Airframe mismatch", for the list.
    """
    v = params.vehicle
    J = params.inertia_matrix_kg_m2
    d = params.mismatch
    return {
        "airframe_mass_kg": np.float64(v.mass_kg),
        "airframe_inertia_kg_m2": np.array([J[0][0], J[1][1], J[2][2]], dtype=np.float64),
        "airframe_arm_length_m": np.float64(v.arm_length_m),
        "airframe_drag_torque_ratio_m": np.float64(v.drag_torque_ratio_m),
        "airframe_rotor_gain": np.array(params.rotor_gain, dtype=np.float64),
        "airframe_thrust_scale": np.float64(v.emulator.thrust_scale),
        "airframe_rotor_time_constant_s": np.float64(v.true_rotor_time_constant_s),
        "airframe_com_offset_m": np.array(params.com_offset_m, dtype=np.float64),
        "airframe_mismatch_seed": np.int64(-1 if d is None else d.seed),
        "airframe_mismatch_scale": np.float64(0.0 if d is None else d.scale),
    }


def _g(x: float) -> str:
    return f"{x:.6g}"


def airframe_meta(params) -> dict:
    """The recording's ``meta_json.airframe``: the true values, the draw, the bounds."""
    true = {k[len("airframe_"):]: v.tolist() for k, v in airframe_arrays(params).items()}
    draw = dataclasses.asdict(params.mismatch) if params.mismatch is not None else None
    return {"true": true, "mismatch": draw, "kept": list(params.mismatch_kept),
            "bounds": dataclasses.asdict(BOUNDS) if draw is not None else None}


def describe_airframe(params) -> str:
    """One line of ``key=value`` fields (the third start-up line with ``--mismatch-seed``)."""
    a = airframe_arrays(params)
    d = params.mismatch
    fields = [f"mismatch_seed={d.seed}" if d is not None else "mismatch_seed=none",
              f"mismatch_scale={_g(d.scale) if d is not None else 0}"]
    for key, value in a.items():
        if key in ("airframe_mismatch_seed", "airframe_mismatch_scale"):
            continue
        text = ",".join(_g(float(c)) for c in value) if np.ndim(value) else _g(float(value))
        fields.append(f"{key[len('airframe_'):]}={text}")
    fields.append("kept=" + (",".join(params.mismatch_kept) or "none"))
    return "airframe: " + " ".join(fields)
