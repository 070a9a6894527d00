"""The steered approach (cdpr_control.platform.steered_approach) against the platform's physics: the
motion it plans is one the remaining cables can pull within their bounds, row by row, and
it ends at the target at rest."""
from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.platform.dynamics import rigid_body
from cdpr_control.platform.kinematics import wrench_matrix
from cdpr_control.geometry.pose_trajectories import PoseSample
from cdpr_control.geometry.rotation import difference
from cdpr_control.platform.safe_pose import tension_margin_n
from cdpr_control.platform.steered_approach import SteeredApproach
from cdpr_fdi.recovery_planning.recovery import safe_pose_for

from conftest import CONFIG_DIR


def test_the_steered_motion_is_one_the_cables_left_pull_within_their_bounds_to_the_target():
    """Cable 1 gone, the platform on its way up the tilting climb and moving, where the
    seven cables left cannot hold it at rest: every 25th row's wrench, M (a, α) − (w_g − h),
    is pulled by tensions within [τ_min + 3 N, τ_max] (scipy's LP, not the project's
    solver), and after 10 s the platform is at the target pose, at rest."""
    run = build_scenario(ScenarioOptions(config=str(CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'),
                                         motions=str(CONFIG_DIR / 'crossed_platform_motions.yaml'),
                                         motion='climb-tilt', fidelity='rigid'))
    robot, reference = run.robot, run.reference
    attached = robot.cable_mask([0])
    # the first row past 0.3 of the way where the seven cables cannot hold the platform at rest
    row = next(k for k in range(int(0.3 * len(reference)), len(reference))
               if tension_margin_n(robot, reference.position_m[k], reference.orientation[k], attached) < 0.0)
    safe = safe_pose_for(robot, run.recovery, attached)
    start = PoseSample(reference.position_m[row], reference.orientation[row], reference.velocity_m_s[row],
                       reference.platform_angular_velocity_rad_s[row], np.zeros(3), np.zeros(3))
    low, high = robot.tension_min_n + 3.0, robot.tension_max_n
    approach = SteeredApproach(robot, attached, start, safe.position_m, safe.orientation,
                               run.recovery.approach_gains, low, high, run.period_s)
    rows = round(10.0 / run.period_s)
    steps = approach.samples(0, rows)
    for k in range(0, rows, 25):
        body = rigid_body(robot, steps.orientation[k], steps.angular_velocity_rad_s[k])
        wrench = body.mass_matrix @ np.concatenate([steps.acceleration_m_s2[k],
                                                    steps.angular_acceleration_rad_s2[k]]) - body.free_wrench
        structure = wrench_matrix(robot, steps.position_m[k], steps.orientation[k])[0][:, attached]
        # within a hair of the bounds: the solver's rounding
        pulled = linprog(np.zeros(7), A_eq=structure, b_eq=wrench, bounds=[(low - 1e-6, high + 1e-6)] * 7,
                         method='highs')
        assert pulled.status == 0, (k, pulled.message)
    assert np.linalg.norm(steps.position_m[-1] - safe.position_m) < 1e-3
    assert np.degrees(np.linalg.norm(difference(safe.orientation, steps.orientation[-1]))) < 0.1
    assert np.linalg.norm(steps.velocity_m_s[-1]) < 1e-3
    # and, by scipy's LP too, it could not be held where it started: the motion was needed
    body = rigid_body(robot, start.orientation, np.zeros(3))
    structure = wrench_matrix(robot, start.position_m, start.orientation)[0][:, attached]
    held = linprog(np.zeros(7), A_eq=structure, b_eq=-body.free_wrench, bounds=[(robot.tension_min_n, high)] * 7,
                   method='highs')
    assert held.status == 2
