"""The plan's nominal as a table for other tools: ``mavreg plan --export FILE.csv|json``.

One row per node of the plan's grid (the nodes the gains are scheduled on): nominal time
(the integral of ds / v(s), as :attr:`Plan.duration_s`), arc length, NED position and
velocity, attitude (the quaternion of the nominal rotation, body FRD to NED, and its
roll-pitch-yaw in degrees), body rates, collective thrust and torques, and the four rotor
forces (front, right, back, left) that produce them. Every name carries its unit. Nothing
here recomputes the nominal: it rearranges the plan's arrays. The files are written and read
by :mod:`mavreg.planning.nominal_files`.
"""
from __future__ import annotations

import numpy as np

from ..model.mixer import Mixer
from ..model.rotation import matrices_to_quats, matrix_to_rpy, rpy_to_matrix

__all__ = ["nominal_table", "nominal_time_s", "plan_attitudes", "rotor_forces_n", "COLUMN_GROUPS",
           "CSV_COLUMNS"]

COLUMN_GROUPS = (
    ("t_s", ("t_s",)),
    ("s_m", ("s_m",)),
    ("position_ned_m", ("north_m", "east_m", "down_m")),
    ("velocity_ned_m_s", ("v_north_m_s", "v_east_m_s", "v_down_m_s")),
    ("speed_m_s", ("speed_m_s",)),
    ("quaternion_wxyz", ("q_w", "q_x", "q_y", "q_z")),
    ("roll_pitch_yaw_deg", ("roll_deg", "pitch_deg", "yaw_deg")),
    ("body_rates_rad_s", ("p_rad_s", "q_rad_s", "r_rad_s")),
    ("thrust_n", ("thrust_n",)),
    ("torque_body_nm", ("torque_x_nm", "torque_y_nm", "torque_z_nm")),
    ("rotor_forces_n", ("rotor1_front_n", "rotor2_right_n", "rotor3_back_n", "rotor4_left_n")),
)
"""(JSON key, CSV columns) of each quantity, in order."""

CSV_COLUMNS = tuple(c for _, cols in COLUMN_GROUPS for c in cols)


def nominal_time_s(plan) -> np.ndarray:
    """Nominal time at each grid node: the trapezoid integral of ds / v(s) from 0
    (its last value is :attr:`Plan.duration_s`)."""
    dt = np.diff(plan.s) * 2.0 / (plan.speed_m_s[1:] + plan.speed_m_s[:-1])
    return np.concatenate([[0.0], np.cumsum(dt)])


def plan_attitudes(plan) -> np.ndarray:
    """Nominal rotations (N, 3, 3), body to NED: the plan's own, else from its roll-pitch-yaw."""
    if plan.R is not None:
        return np.asarray(plan.R, dtype=float)
    return np.moveaxis(rpy_to_matrix(*plan.x[:, 3:6].T), -1, 0)


def rotor_forces_n(plan) -> np.ndarray:
    """Nominal rotor forces (N, 4) of the plan's input (eq 34 inverted, no saturation)."""
    mixer = Mixer.from_vehicle(plan.vehicle)
    return plan.u @ mixer.inverse.T


def nominal_table(plan) -> dict[str, np.ndarray]:
    """The nominal on the plan's grid, keyed by the JSON names of ``COLUMN_GROUPS`` (units in keys)."""
    R = plan_attitudes(plan)
    v_body = plan.x[:, 6:9]
    return {
        "t_s": nominal_time_s(plan),
        "s_m": np.asarray(plan.s, dtype=float),
        "position_ned_m": plan.x[:, 0:3],
        "velocity_ned_m_s": np.einsum("nij,nj->ni", R, v_body),
        "speed_m_s": np.asarray(plan.speed_m_s, dtype=float),
        "quaternion_wxyz": matrices_to_quats(R),
        "roll_pitch_yaw_deg": np.degrees(matrix_to_rpy(R)),
        "body_rates_rad_s": plan.x[:, 9:12],
        "thrust_n": plan.u[:, 0],
        "torque_body_nm": plan.u[:, 1:4],
        "rotor_forces_n": rotor_forces_n(plan),
    }
