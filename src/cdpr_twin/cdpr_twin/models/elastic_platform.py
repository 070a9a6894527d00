"""Elastic-cable simulation of a platform robot (6 DOF): the plant's `elastic` fidelity for
it (docs/platform.md).

Each cable is a unilateral spring–damper of stiffness EA / l from its exit point to its
attachment point on the platform (it can go slack, never push), l = l_0 + ρ θ its
unstretched length; motors carry viscous and Coulomb friction (smoothed by tanh). The
platform obeys Newton–Euler at its frame's origin (cdpr_control.platform.dynamics):
M (a, α) + h = W τ + w_g + w_ext. Integrated by semi-implicit Euler in sub-steps
(cdpr_control.platform.substeps.elastic_substeps, run by its `kernel`): the velocities
with the tensions of the sub-step's start, then the pose and the angles with the new
velocities, then the tensions of the end.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.platform import kinematics as pose_kinematics
from cdpr_control.point_mass.dynamics import NO_FORCE
from cdpr_control.platform.dynamics import wrench_at_origin
from cdpr_control.platform.statics import static_tensions
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import normalised


class ElasticPlatform:
    """State: pose (p, q), twist (v, ω), motors θ, θ̇; tensions τ (N) follow from it.

    It starts in equilibrium at rest: each cable stretched by the tension that holds the
    platform there (the minimum-norm tensions within the cable bounds). A step replaces
    the state arrays rather than writing into them.
    """

    def __init__(self, robot: Robot, motor_values, position_m, orientation, config, kernel: str = 'compiled'):
        """At the pose (p, `orientation`: the platform's home one when None). `motor_values`:
        rows of each motor's inertia J_i (kg·m²), viscous friction b_i (N·m·s/rad) and
        Coulomb friction f_c,i (N·m) (plant.true_motors); robot.motor gives the drums'
        radius. `config`: the plant's PlantConfig (sub-steps, the cables' EA and damping,
        the Coulomb friction's smoothing)."""
        self.robot = robot
        self.config = config
        self.kernel = platform_substeps.kernel(kernel).load_all()
        self.exits, self.attachments, self.offsets = platform_substeps.geometry_of(robot)
        # a writable C-contiguous copy, as the compiled kernels take arrays
        self.motors = np.array(motor_values, dtype=float, order='C')
        self.constants = platform_substeps.constants_of(
            robot, config.coulomb_velocity_rad_s, config.axial_stiffness_n, config.damping_n_s_m)
        self.position_m = np.array(position_m, dtype=float)
        self.orientation = normalised(robot.body.home_orientation if orientation is None else orientation)
        self.velocity_m_s = np.zeros(3)
        self.platform_angular_velocity_rad_s = np.zeros(3)
        self.drums_locked = False
        self.attached = np.ones(robot.cable_count, dtype=bool)
        tension = static_tensions(robot, self.position_m, self.orientation)
        _, d, _ = pose_kinematics.cable_vectors(robot, self.position_m, self.orientation)
        unstretched = d / (1.0 + tension / config.axial_stiffness_n)
        self.angle_rad = (unstretched - robot.cable_length_offset_m) / robot.motor.drum_radius_m
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        self.tension_n = np.zeros(robot.cable_count)
        # with no time, a step only evaluates the tensions of the state
        self.step(np.zeros(robot.cable_count), 0.0, 1)

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached[index] = False
        self.tension_n = np.where(self.attached, self.tension_n, 0.0)

    def step(self, torque_nm, period_s: float, substeps: int | None = None, external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the model's),
        and `external_force_n` (N, world frame) at the platform's origin."""
        robot = self.robot
        substeps = substeps or self.config.substeps
        pose = np.concatenate([self.position_m, self.orientation])
        twist = np.concatenate([self.velocity_m_s, self.platform_angular_velocity_rad_s])
        angle, speed = self.angle_rad.copy(), self.angular_velocity_rad_s.copy()
        tension = np.empty(robot.cable_count)
        self.kernel.elastic_substeps(substeps, period_s / substeps, self.constants, self.exits,
                                     self.attachments, self.offsets, self.motors,
                                     self.attached.astype(float), np.array(torque_nm, dtype=float),
                                     wrench_at_origin(external_force_n), self.drums_locked,
                                     pose, twist, angle, speed, tension)
        self.position_m, self.orientation = pose[:3], pose[3:]
        self.velocity_m_s, self.platform_angular_velocity_rad_s = twist[:3], twist[3:]
        self.angle_rad, self.angular_velocity_rad_s = angle, speed
        self.tension_n = tension
