"""A push on the end-effector, or a brief contact with an obstacle, is not a failure: no
cable is named, the supervisor reports a disturbance; a failure is still named, also one
during a push. The wrench balance that tells them apart weighs a push right."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.settle import ScenarioOptions
from cdpr_fdi.detection.residual import sensorless_tension_bounds
from cdpr_fdi.detection.wrench_balance import WrenchBalance

from conftest import MOTIONS, PAPER_ROBOT, every_tick_scenario

PUSH_START_S = 1.5


def scenario(motion: str, fidelity: str = 'elastic', **options):
    return every_tick_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                          motion=motion, fidelity=fidelity, seed=4, **options))


# The hard cases on the elastic plant: 30 N for 0.5 s (up to 5 m/s on the 2.9 kg
# end-effector) in every direction, which slackens one cable or two and sets it swinging
# (or, towards taut cables, is held within millimetres); a 10 N push; and contacts,
# 50-60 N for 50 ms.
PUSHES = [('circle', (PUSH_START_S, 0.5, 30.0, 0.0, 0.0)),
          ('circle', (PUSH_START_S, 0.5, 0.0, -30.0, 0.0)),
          ('along-2', (PUSH_START_S, 0.5, -30.0, 0.0, 0.0)),
          ('along-2', (PUSH_START_S, 0.5, 0.0, 30.0, 0.0)),
          ('orthogonal-2', (PUSH_START_S, 0.5, 0.0, 0.0, 30.0)),
          ('orthogonal-2', (PUSH_START_S, 0.5, 0.0, -30.0, 0.0)),
          ('along-2', (PUSH_START_S, 0.2, 10.0, 0.0, 0.0)),
          ('circle', (2.0, 0.05, 50.0, 0.0, 0.0)),
          ('orthogonal-2', (1.0, 0.05, 0.0, 0.0, 60.0))]


@pytest.mark.parametrize('motion, push', PUSHES, ids=[f'{m}-{p[1]}s-{p[2:]}N' for m, p in PUSHES])
def test_a_push_or_a_contact_names_no_cable_and_is_reported_as_a_disturbance(motion, push):
    run = scenario(motion, pushes=[push])
    recording = run_inprocess(run)
    assert recording.fdi['broken_cables'] == [] and recording.fdi['mode'] == 'NOMINAL'
    assert recording.fdi['disturbances'] >= 1


def test_a_failure_during_a_push_is_named_once_the_push_is_over():
    run = scenario('along-2', fail_cables=[4], fail_at_s=PUSH_START_S + 0.1,
                   pushes=[(PUSH_START_S, 0.3, 0.0, 10.0, 0.0)])
    recording = run_inprocess(run)
    named_s = recording.time_s[recording.fdi['identified_tick']]
    assert recording.fdi['broken_cables'] == [4]
    assert PUSH_START_S + 0.3 < named_s < PUSH_START_S + 1.5
    assert recording.fdi['mode'] == 'SAFE_HOLD'


@pytest.mark.parametrize('force_n', [(0.0, 10.0, 0.0), (-8.0, 0.0, 6.0)])
def test_the_balance_weighs_a_push_from_the_motors_alone(force_n):
    """On the elastic plant, with every cable taut, F = m p̈ − Σ τ̂ u − m g, from resolver
    angles, speeds and the applied torques only, is the push within 1.5 N; before it,
    within 1.5 N of zero (the 2 % heavier plant's weight, noise)."""
    run = scenario('circle', pushes=[(PUSH_START_S, 0.3, *force_n)])
    recording = run_inprocess(run, supervised=False)
    assert recording.true_tension_n.min() > 1.0   # no cable went slack
    balance = WrenchBalance(run.robot, run.period_s, window=5)
    applied = np.vstack([np.zeros_like(recording.command_nm[:1]), recording.command_nm[:-1]])
    forces = {}
    for k in range(1, len(recording.time_s)):
        low, high = sensorless_tension_bounds(
            run.robot.motor, run.fdi.friction, applied[k], recording.angular_velocity_rad_s[k - 1],
            recording.angular_velocity_rad_s[k], run.period_s)
        balance.record(k, recording.angle_rad[k], recording.angular_velocity_rad_s[k], (low + high) / 2)
        forces[k] = balance.unexplained_force_n({})
    ticks = {name: int(round(time_s / run.period_s)) for name, time_s in
             (('start', PUSH_START_S), ('end', PUSH_START_S + 0.3))}
    pushed = np.array([forces[k] for k in range(ticks['start'] + 10, ticks['end'])])
    before = np.array([forces[k] for k in range(ticks['start'] - 200, ticks['start'])])
    assert np.abs(pushed - force_n).max() < 1.5
    assert np.abs(before).max() < 1.5


def test_pushes_reach_the_plant_node_as_parameters(tmp_path):
    from test_settings import node_given
    from cdpr_twin.nodes.plant_simulator_node import PlantSimulatorNode
    pushes = [(1.0, 0.2, 5.0, 0.0, -3.0), (2.5, 0.05, 0.0, 40.0, 0.0)]
    run = scenario('circle', pushes=pushes)
    with node_given(run.node_parameters('lockstep')['plant_simulator'], PlantSimulatorNode,
                    tmp_path) as node:
        assert node.plant.pushes == run.pushes
    assert [(p.start_s, p.duration_s, *p.force_n) for p in run.pushes] == pushes
