"""Figures of a run: the twin-vs-robot KPIs of paper §5.1 and the metrics.json keys."""
from __future__ import annotations

import numpy as np

from cdpr_control.kinematics import forward_kinematics
from cdpr_control.robot import Robot

PAPER_KPI = {'K_c_m': 0.0143, 'K_j_rad': 0.0583, 'K_t_nm': 0.1566}


def twin_kpis(robot: Robot, recording) -> dict:
    """Largest Cartesian (FK of the measured angles), joint and torque gap to the twin."""
    measured = np.array([forward_kinematics(robot, angle) for angle in recording.angle_rad])
    return {
        'K_c_m': float(np.max(np.linalg.norm(measured - recording.twin_position_m, axis=1))),
        'K_j_rad': float(np.max(np.abs(recording.angle_rad - recording.twin_angle_rad))),
        'K_t_nm': float(np.max(np.abs(recording.command_nm - recording.twin_torque_nm))),
    }


def tracking_error_m(recording) -> float:
    """Largest distance between the true end-effector and the reference pose (m)."""
    return float(np.max(np.linalg.norm(recording.true_position_m - recording.reference_position_m,
                                       axis=1)))
