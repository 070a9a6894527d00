"""A platform's safe pose after each single cable break, against a brute-force sample of
its residual workspace: feasibility decided here by a linear program (scipy), not by the
project's tension distributions."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import linprog

from cdpr_control.platform import dynamics as pose_dynamics
from cdpr_control.platform import kinematics as pose_kinematics
from cdpr_control.platform import safe_pose as safe_pose_module
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.geometry.rotation import difference
from cdpr_control.platform.safe_pose import candidate_orientations, safe_pose, tension_margin_n
from cdpr_control.tension_distribution import PseudoInverse
from cdpr_fdi.settings.config import load_fdi_config, load_recovery_config
from cdpr_fdi.recovery_planning.recovery import safe_pose_for
from cdpr_fdi.supervision.supervisor import Supervisor

from conftest import CONFIG_DIR

ROBOT = CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'
HEIGHT_M = 1.2
TURNS_DEG = (5.0, 10.0)
SPACING_M = 0.05
SAMPLES = 1000
# the sample's barycentre is off the section's by ~1.5 cm a coordinate (its standard
# error), the 5 cm grid's by ~1 cm more: 2.4 and 1.4 cm here (2.3 and 0.8 with 2000)
BARYCENTRE_TOLERANCE_M = 0.04


@pytest.fixture(scope='module')
def robot():
    return load_robot(ROBOT)


def held(robot, attached, position, orientation) -> bool:
    """Whether tensions within [τ_min, τ_max] of the attached cables hold the platform at
    rest at the pose: W τ = −w_g, by linear programming."""
    structure, _ = pose_kinematics.wrench_matrix(robot, position, orientation)
    weight = pose_dynamics.rigid_body(robot, orientation, np.zeros(3)).free_wrench
    result = linprog(np.zeros(np.count_nonzero(attached)), A_eq=structure[:, attached], b_eq=-weight,
                     bounds=[(robot.tension_min_n, robot.tension_max_n)] * np.count_nonzero(attached),
                     method='highs')
    return result.status == 0


# two cables of different posts, each on a different side of its post: each breaks a
# different part of the workspace away
@pytest.mark.parametrize('broken', [0, 5])
def test_the_safe_pose_is_the_barycentre_of_the_sampled_residual_workspace(robot, broken):
    attached = robot.cable_mask([broken])
    pose = safe_pose(robot, attached, HEIGHT_M, TURNS_DEG, SPACING_M)
    assert pose.position_m[2] == HEIGHT_M
    assert held(robot, attached, pose.position_m, pose.orientation)
    # the section at the chosen orientation, sampled at random points and judged by LP
    rng = np.random.default_rng(broken)
    low, high = robot.workspace_min_m[:2], robot.workspace_max_m[:2]
    points = low + rng.random((SAMPLES, 2)) * (high - low)
    inside = np.array([held(robot, attached, (x, y, HEIGHT_M), pose.orientation) for x, y in points])
    assert 0.1 < inside.mean() < 1.0, 'a cable broken takes part of the workspace'
    # the grid's barycentre is the sample's, to the sampling's error
    assert np.linalg.norm(points[inside].mean(axis=0) - pose.position_m[:2]) < BARYCENTRE_TOLERANCE_M
    # and no orientation tried holds its own barycentre with more margin
    for orientation in candidate_orientations(robot.body.home_orientation, TURNS_DEG):
        if np.linalg.norm(difference(orientation, pose.orientation)) < 1e-12:
            continue
        some = points[:100]
        centre = some[[held(robot, attached, (x, y, HEIGHT_M), orientation) for x, y in some]]
        if len(centre):
            margin = tension_margin_n(robot, np.append(centre.mean(axis=0), HEIGHT_M), orientation, attached)
            assert margin < pose.tension_margin_n + 1.0


def test_a_safe_pose_is_found_once_per_robot_cables_and_settings(robot):
    """A supervisor finds every single break's when it starts, a run's length and the
    naming ask again: they get the first's, and so does the same robot loaded anew (each
    run of a campaign loads its own); another robot, or other settings, their own."""
    attached = robot.cable_mask([2])
    first = safe_pose(robot, attached, HEIGHT_M, TURNS_DEG, 0.1)
    assert safe_pose(robot, attached.copy(), HEIGHT_M, TURNS_DEG, 0.1) is first
    assert safe_pose(load_robot(ROBOT), attached, HEIGHT_M, TURNS_DEG, 0.1) is first
    heavier = dataclasses.replace(robot, mass_kg=robot.mass_kg * 1.5)
    other = safe_pose(heavier, attached, HEIGHT_M, TURNS_DEG, 0.1)
    assert other is not first and other.tension_margin_n != first.tension_margin_n
    assert safe_pose(robot, attached, HEIGHT_M - 0.1, TURNS_DEG, 0.1).position_m[2] == HEIGHT_M - 0.1


def test_a_platforms_supervisor_has_every_single_breaks_safe_pose_before_a_cable_is_named(robot):
    """Naming a cable then takes no search (~0.2 s a cable: ticks a realtime supervisor
    does not have)."""
    recovery = load_recovery_config(ROBOT, robot)
    safe_pose_module._found.clear()
    Supervisor(robot, load_fdi_config(ROBOT, robot), recovery, PseudoInverse(robot.tension_min_n, robot.tension_max_n),
               0.002)
    found = dict(safe_pose_module._found)
    assert len(found) == robot.cable_count
    for cable in range(robot.cable_count):
        assert any(safe_pose_for(robot, recovery, robot.cable_mask([cable])) is pose for pose in found.values())
    assert safe_pose_module._found == found, 'no search when a cable is named'
