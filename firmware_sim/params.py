"""The emulator's parameters: a vehicle YAML (mavreg's validating loader) plus overrides.

``mavreg.config`` (the parameter files) is the only part of mavreg firmware_sim imports, besides
the fault-injection test tool ``mavreg.tools.faultlink`` (``--link-faults``); no control code.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mavreg.config.paths import vehicle_file
from mavreg.config.vehicle import VehicleParams, load_vehicle

from .physics import inertia_matrix, quat_from_euler

__all__ = ["SimParams", "default_vehicle_path", "load_sim_params", "apply_overrides",
           "parse_start", "START_KEYS"]


def default_vehicle_path() -> Path:
    """``params/vehicles/mk_quadro.yaml``, bundled with mavreg (:mod:`mavreg.config.paths`)."""
    return vehicle_file("mk_quadro")


@dataclass(frozen=True)
class SimParams:
    """Everything the physics needs, resolved from the vehicle file and the overrides."""

    vehicle: VehicleParams
    inertia_matrix_kg_m2: tuple
    """Full symmetric inertia matrix, 3x3 nested tuple: the (possibly overridden or
    perturbed) diagonal and ``emulator.inertia_offdiag_kg_m2``. This, not
    ``vehicle.inertia_kg_m2``, is what the physics uses."""
    rate_hz: int = 500
    physics_hz: int = 1000
    seed: int = 0
    rotor_gain: tuple = (1.0, 1.0, 1.0, 1.0)
    """Thrust each rotor (1..4) gives per newton commanded, before the world's
    ``emulator.thrust_scale`` (an airframe mismatch: :mod:`firmware_sim.mismatch`)."""
    com_offset_m: tuple = (0.0, 0.0, 0.0)
    """Centre of mass relative to the rotors' centre, body FRD (m); the rotors' thrust acts
    at their positions relative to it."""
    mismatch: object = None
    """The :class:`firmware_sim.mismatch.MismatchDraw` applied, or ``None``."""
    mismatch_kept: tuple = ()
    """Parameters an explicit flag kept from the draw (``mass_kg``, ...)."""
    angular_drag_n_m_s_per_rad: float = 0.0
    """Angular damping: a body torque ``-c omega`` (``--angular-drag-n-m-s-per-rad``; PX4 SIH's
    ``SIH_KDW``), held over each physics step as SIH holds it over its own."""

    @property
    def substeps(self) -> int:
        """Physics steps per control period."""
        return self.physics_hz // self.rate_hz


def load_sim_params(vehicle_path: str | Path, rate_hz: int = 500, physics_hz: int = 1000,
                    seed: int = 0, **overrides) -> SimParams:
    """Load a vehicle, apply :func:`apply_overrides` and check the rates.

    Raises
    ------
    ValueError
        (``ConfigError`` included) with a one-line message on bad input.
    """
    vehicle = load_vehicle(vehicle_path)
    return build_sim_params(vehicle, rate_hz, physics_hz, seed, **overrides)


def build_sim_params(vehicle: VehicleParams, rate_hz: int = 500, physics_hz: int = 1000,
                     seed: int = 0, angular_drag_n_m_s_per_rad: float | None = None, **overrides) -> SimParams:
    """:class:`SimParams` from already loaded vehicle parameters (see :func:`load_sim_params`)."""
    kw = 0.0 if angular_drag_n_m_s_per_rad is None else float(angular_drag_n_m_s_per_rad)
    if not (math.isfinite(kw) and 0.0 <= kw <= 10.0):
        raise ValueError("--angular-drag-n-m-s-per-rad must be in [0, 10]")
    if rate_hz <= 0 or physics_hz <= 0:
        raise ValueError("--rate-hz and --physics-hz must be positive")
    if physics_hz % rate_hz:
        raise ValueError(f"--physics-hz {physics_hz} must be an integer multiple of --rate-hz {rate_hz}")
    vehicle, diag = apply_overrides(vehicle, seed=seed, **overrides)
    J = inertia_matrix(diag, vehicle.emulator.inertia_offdiag_kg_m2)
    return SimParams(vehicle, J, int(rate_hz), int(physics_hz), int(seed), angular_drag_n_m_s_per_rad=kw)


def apply_overrides(vehicle: VehicleParams, *, seed: int = 0, mass_kg: float | None = None,
                    inertia_kg_m2=None, inertia_scale: float | None = None,
                    inertia_perturb_sd_kg_m2: float | None = None,
                    rotor_time_constant_s: float | None = None,
                    rotor_noise_sd_n: float | None = None,
                    max_rotor_thrust_n: float | None = None) -> tuple[VehicleParams, tuple]:
    """Return ``(vehicle, inertia_diag_kg_m2)`` with command-line overrides applied.

    ``None`` keeps the file's value. The inertia diagonal is returned apart and
    ``vehicle.inertia_kg_m2`` stays nominal: a perturbed airframe (the paper's Monte
    Carlo draws each moment independently) may break the triangle inequality that
    the design-model parameters enforce; the physics only needs a positive-definite
    matrix.

    Inertia: ``inertia_kg_m2`` replaces the diagonal, then ``inertia_scale`` multiplies
    it, then ``inertia_perturb_sd_kg_m2`` adds Gaussian noise per axis drawn from
    ``numpy.random.default_rng([seed, 1])`` (independent of the rotor noise stream).
    """
    v = vehicle
    emu = v.emulator
    changes: dict = {}
    for name, value in (("mass_kg", mass_kg), ("max_rotor_thrust_n", max_rotor_thrust_n)):
        if value is not None:
            _positive(name, value)
            changes[name] = float(value)
    diag = tuple(v.inertia_kg_m2)
    if inertia_kg_m2 is not None:
        if len(inertia_kg_m2) != 3:
            raise ValueError("--inertia-kg-m2 takes three values JX JY JZ")
        for x in inertia_kg_m2:
            _positive("--inertia-kg-m2", x)
        diag = tuple(float(x) for x in inertia_kg_m2)
    if inertia_scale is not None:
        _positive("--inertia-scale", inertia_scale)
        diag = tuple(x * inertia_scale for x in diag)
    if inertia_perturb_sd_kg_m2 is not None:
        if not (math.isfinite(inertia_perturb_sd_kg_m2) and inertia_perturb_sd_kg_m2 >= 0):
            raise ValueError("--inertia-perturb-sd-kg-m2 must be a finite number >= 0")
        rng = np.random.default_rng([int(seed), 1])
        diag = tuple(float(x + inertia_perturb_sd_kg_m2 * rng.standard_normal()) for x in diag)
        if min(diag) <= 0:
            raise ValueError(f"inertia perturbation gave a non-positive moment {diag}")
    emu_changes = {}
    if rotor_time_constant_s is not None:
        if not (math.isfinite(rotor_time_constant_s) and 0 <= rotor_time_constant_s <= 1):
            raise ValueError("--rotor-time-constant-s must be in [0, 1]")
        emu_changes["true_rotor_time_constant_s"] = float(rotor_time_constant_s)
    if rotor_noise_sd_n is not None:
        if not (math.isfinite(rotor_noise_sd_n) and rotor_noise_sd_n >= 0):
            raise ValueError("--rotor-noise-sd-n must be a finite number >= 0")
        emu_changes["rotor_noise_sd_n"] = float(rotor_noise_sd_n)
    if emu_changes:
        changes["emulator"] = dataclasses.replace(emu, **emu_changes)
    if changes:
        v = dataclasses.replace(v, **changes)   # re-runs the cross-field checks
    return v, diag


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


START_KEYS = ("x_m", "y_m", "z_m", "roll_deg", "pitch_deg", "yaw_deg",
              "vx_m_s", "vy_m_s", "vz_m_s", "p_deg_s", "q_deg_s", "r_deg_s")
"""Keys of ``--start``: position (NED), ZYX attitude, velocity (NED), body rates."""


def parse_start(text: str) -> tuple:
    """Parse ``--start 'z_m=-5,vy_m_s=8,roll_deg=120'`` into a 13-state tuple.

    Missing keys are 0. The attitude is ZYX roll/pitch/yaw in degrees (any values,
    e.g. roll_deg=120 is 120 deg rolled); velocity is NED; body rates are FRD.

    Raises
    ------
    ValueError
        On an unknown key, a repeated key, a non-number or a start below ground.
    """
    values = dict.fromkeys(START_KEYS, 0.0)
    seen = set()
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        key, eq, val = item.partition("=")
        key = key.strip()
        if not eq or key not in values:
            raise ValueError(f"--start: unknown item {item!r}; expected KEY=VALUE with KEY one of "
                             f"{', '.join(START_KEYS)}")
        if key in seen:
            raise ValueError(f"--start: {key} given twice")
        seen.add(key)
        try:
            values[key] = float(val)
        except ValueError:
            raise ValueError(f"--start: {key}: expected a number, got {val!r}") from None
        if not math.isfinite(values[key]):
            raise ValueError(f"--start: {key}: expected a finite number")
    if values["z_m"] > 0:
        raise ValueError("--start: z_m must be <= 0 (NED: negative is above ground)")
    q = quat_from_euler(*(math.radians(values[k]) for k in ("roll_deg", "pitch_deg", "yaw_deg")))
    return (values["x_m"], values["y_m"], values["z_m"], *q,
            values["vx_m_s"], values["vy_m_s"], values["vz_m_s"],
            *(math.radians(values[k]) for k in ("p_deg_s", "q_deg_s", "r_deg_s")))
