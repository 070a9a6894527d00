"""The platform through the node graph: lockstep, the loop's nodes with eight joints and
the pose topics with the platform's orientation, equal to the in-process engine."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_bringup.bags.bag_io import recording_from_bag
from cdpr_bringup.graph.launcher import graph_nodes, run_to_completion
from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.rotation import difference

from conftest import CONFIG_DIR

pytestmark = pytest.mark.graph

# Half a second at rest, then two seconds of the move and its 12° turn about the vertical.
DURATION_S = 2.5


def test_the_lockstep_graph_turns_the_platform_as_the_in_process_engine_does(tmp_path):
    scenario = build_scenario(ScenarioOptions(
        config=str(CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'),
        motions=str(CONFIG_DIR / 'crossed_platform_motions.yaml'), motion='across-yaw', fidelity='rigid',
        duration_s=DURATION_S))
    bag = tmp_path / 'bag'
    run_to_completion(graph_nodes(scenario.node_parameters('lockstep'), str(bag)), '/cdpr_test_platform',
                      timeout_s=120.0, log=lambda line: None)
    graph = recording_from_bag(bag, '/cdpr_test_platform', orientations=True)
    engine = run_inprocess(scenario)
    assert graph.time_s.size == engine.time_s.size == scenario.cycles
    assert graph.angle_rad.shape[1] == 8
    for name in ('true_position_m', 'command_nm', 'twin_torque_nm', 'true_orientation', 'twin_orientation',
                 'reference_orientation'):
        np.testing.assert_allclose(getattr(graph, name), getattr(engine, name), rtol=0, atol=1e-9,
                                   err_msg=name)
    turned = np.degrees(np.linalg.norm(difference(graph.true_orientation[-1], graph.true_orientation[0])))
    assert 1.0 < turned < 12.0   # part of the turn, on its way
