"""The in-process engine: the graph's core classes in one loop, without DDS.

Per cycle k, as the node graph does it: the plant reports θ, θ̇; the controller answers
with c from the reference at t_k; the twin computes c_DT from the same reference; the
plant steps under c.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.controller import JointController, JointReference
from cdpr_twin.plant import PlantSimulator
from cdpr_twin.twin import DigitalTwin

from .scenario_setup import Scenario


@dataclass
class Recording:
    """What a run produced, one row per control cycle (SI units)."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    command_nm: np.ndarray
    twin_angle_rad: np.ndarray
    twin_angular_velocity_rad_s: np.ndarray
    twin_torque_nm: np.ndarray
    twin_position_m: np.ndarray
    reference_position_m: np.ndarray
    reference_angle_rad: np.ndarray
    true_position_m: np.ndarray
    true_tension_n: np.ndarray


def reference_at(scenario: Scenario, k: int) -> JointReference:
    table = scenario.reference
    return JointReference(table.angle_rad[k], table.angular_velocity_rad_s[k],
                          table.feedforward_nm[k])


def run_inprocess(scenario: Scenario) -> Recording:
    robot = scenario.robot
    start = scenario.reference.position_m[0]
    plant = PlantSimulator(robot, scenario.plant, start, scenario.failures)
    twin = DigitalTwin(robot, scenario.gains, start, scenario.twin_substeps)
    controller = JointController(robot, scenario.gains)
    cycles, m = scenario.cycles, robot.cable_count
    rows = {name: np.empty((cycles, width)) for name, width in (
        ('angle', m), ('speed', m), ('command', m), ('twin_angle', m), ('twin_speed', m),
        ('twin_torque', m), ('twin_position', 3), ('true_position', 3), ('true_tension', m))}
    for k in range(cycles):
        reference = reference_at(scenario, k)
        angle, speed = plant.measure()
        rows['true_position'][k] = plant.position_m
        rows['true_tension'][k] = plant.tension_n
        command = controller.command(angle, speed, reference)
        twin_output = twin.step(reference, scenario.period_s)
        plant.step(command, scenario.period_s)
        rows['angle'][k], rows['speed'][k], rows['command'][k] = angle, speed, command
        rows['twin_angle'][k] = twin_output.angle_rad
        rows['twin_speed'][k] = twin_output.angular_velocity_rad_s
        rows['twin_torque'][k] = twin_output.torque_nm
        rows['twin_position'][k] = twin_output.position_m
    return Recording(
        time_s=np.arange(cycles) * scenario.period_s,
        angle_rad=rows['angle'], angular_velocity_rad_s=rows['speed'], command_nm=rows['command'],
        twin_angle_rad=rows['twin_angle'], twin_angular_velocity_rad_s=rows['twin_speed'],
        twin_torque_nm=rows['twin_torque'], twin_position_m=rows['twin_position'],
        reference_position_m=scenario.reference.position_m,
        reference_angle_rad=scenario.reference.angle_rad,
        true_position_m=rows['true_position'], true_tension_n=rows['true_tension'])
