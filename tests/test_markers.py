"""The markers of /cdpr/markers (cdpr_fdi.view.markers) against a simulated run's ground truth,
a frame per view tick from the view topics alone, and the same markers in an in-process
run's bag."""
from __future__ import annotations

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from cdpr_bringup.bags.bag_io import BagWriter, read_messages, write_recording
from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.point_mass.workspace import contains
from cdpr_fdi.view.markers import (BROKEN_GREY, LINE_LIST, LINE_STRIP, SPHERE_LIST, TENSION_SCALE,
                              UNKNOWN_TENSION_COLOUR, Frame, cable_shapes, dashes, tension_colour)
from cdpr_msgs_py import contract

from conftest import MOTIONS, PAPER_ROBOT

BROKEN = 4


def feed(frame: Frame, recording, view: int, stamp_ns: int) -> None:
    """The view topics of the recording's view tick `view` into `frame`, as the node gets them."""
    frame.on_view('twin', stamp_ns, (recording.twin_position_m[view], None if recording.twin_orientation is None
                                     else recording.twin_orientation[view]))
    frame.on_view('reference', stamp_ns, (recording.reference_position_m[view], None))
    frame.on_view('true_pose', stamp_ns, (recording.true_position_m[view], None if recording.true_orientation is None
                                          else recording.true_orientation[view]))
    frame.on_view('true_tension', stamp_ns, recording.true_tension_n[view])


@pytest.fixture(scope='module')
def run():
    """Cable 4 breaks mid-way along cable 4 on the rigid plant, detected and recovered
    in-process; the shapes of every frame, fed as the markers node is fed (the view
    topics of each view tick, the verdict once named):
    (scenario, recording, [(view row, tick, shapes by namespace and id)])."""
    scenario = build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                              motion='along-4', fail_cables=[BROKEN],
                                              fidelity='rigid'))
    recording = run_inprocess(scenario)
    frame = scenario.marker_frame()
    frames = []
    for view, time_s in enumerate(recording.view_time_s):
        k = int(round(time_s / scenario.period_s))
        if k >= recording.fdi['identified_tick']:
            frame.on_broken_cable(BROKEN)
        feed(frame, recording, view, k * 2_000_000)
        stamp, shapes = frame.take()
        assert stamp == k * 2_000_000 and frame.take() is None, 'one frame per view tick, once'
        frames.append((view, k, {(s.namespace, s.id): s for s in shapes}))
    # at the view rate, the frames of the whole motion at least
    assert len(frames) >= scenario.motion.trajectory.duration_s * 50.0, len(frames)
    return scenario, recording, frames


def assert_judged_once_identified(run, judged: int) -> None:
    """`judged` frames from the identification on were checked: at least half of those
    after the scheduled failure, else a check of what is drawn once the cable is named
    judged next to nothing."""
    scenario, recording, _ = run
    after_failure = np.count_nonzero(recording.view_time_s >= scenario.failure_time_s)
    assert judged >= 0.5 * after_failure, (judged, after_failure)


def test_cables_run_from_the_exit_points_to_the_true_end_effector(run):
    scenario, recording, frames = run
    robot = scenario.robot
    for view, k, shapes in frames:
        true = recording.true_position_m[view]
        assert np.allclose(shapes['end_effector', 0].points_m, [true], atol=1e-6), k
        assert np.allclose(shapes['twin', 0].points_m, [recording.twin_position_m[view]])
        assert np.allclose(shapes['reference', 0].points_m, [recording.reference_position_m[view]])
        for cable in range(1, robot.cable_count + 1):
            shape = shapes['cables', cable]
            assert shape.kind == LINE_LIST
            if cable == BROKEN and k >= recording.fdi['identified_tick']:
                continue
            assert np.allclose(shape.points_m, [robot.exit_points_m[cable - 1], true], atol=1e-6), k


def test_the_broken_cable_hangs_grey_thin_and_dashed_once_identified(run):
    scenario, recording, frames = run
    style, exit_point = scenario.markers, scenario.robot.exit_points_m[BROKEN - 1]
    identified = recording.fdi['identified_tick']
    hung = 0
    for view, k, shapes in frames:
        shape = shapes['cables', BROKEN]
        if k < identified:
            assert shape.scale_m == style.cable_width_m
            continue
        hung += 1
        assert shape.scale_m == style.broken_cable_width_m < style.cable_width_m
        assert np.all(shape.colours == BROKEN_GREY)
        assert len(shape.points_m) > 2 and len(shape.points_m) % 2 == 0, 'dashes, not one line'
        assert np.allclose(shape.points_m[:, :2], exit_point[:2]), 'hanging straight down'
        assert shape.points_m[0, 2] == exit_point[2]
        # down to the end-effector's height, the last dash within a dash and a gap of it
        height = recording.true_position_m[view, 2]
        assert np.all(shape.points_m[:, 2] >= height - 1e-6)
        assert shape.points_m[-1, 2] - height <= 2 * style.dash_length_m
        for other in set(range(1, 5)) - {BROKEN}:
            assert not np.any(np.all(shapes['cables', other].colours == BROKEN_GREY, axis=1))
    assert_judged_once_identified(run, hung)


def test_a_cable_is_coloured_by_its_true_tension_of_the_tick(run):
    scenario, recording, frames = run
    robot = scenario.robot
    spread = []
    for view, k, shapes in frames:
        colours = tension_colour(recording.true_tension_n[view], robot.tension_min_n, robot.tension_max_n)
        for cable in range(1, robot.cable_count + 1):
            if cable == BROKEN and k >= recording.fdi['identified_tick']:
                continue
            assert np.allclose(shapes['cables', cable].colours, colours[cable - 1]), k
        spread.append(colours[:, :3])
    # the colours change along the motion, as the tensions do
    assert np.ptp(np.array(spread), axis=0).max() > 0.1


def test_without_ground_truth_the_cables_run_to_the_twin_uncoloured(run):
    """Beside a hardware bridge there is no ground truth: the twin is drawn, and the
    cables to it in one colour."""
    scenario, recording, _ = run
    frame = Frame(scenario.robot, scenario.recovery, scenario.markers, ground_truth=False)
    frame.on_view('twin', 0, (recording.twin_position_m[0], None))
    assert frame.take() is None, 'a frame waits for the reference of its tick'
    frame.on_view('reference', 0, (recording.reference_position_m[0], None))
    _, shapes = frame.take()
    shapes = {(s.namespace, s.id): s for s in shapes}
    assert ('end_effector', 0) not in shapes
    for cable in range(1, scenario.robot.cable_count + 1):
        assert np.allclose(shapes['cables', cable].points_m[1], recording.twin_position_m[0])
        assert np.allclose(shapes['cables', cable].colours, UNKNOWN_TENSION_COLOUR)


def test_a_frame_is_of_one_tick_and_an_older_incomplete_tick_is_passed_over(run):
    scenario, recording, _ = run
    frame = scenario.marker_frame()
    feed(frame, recording, 1, 20_000_000)
    frame.on_view('twin', 40_000_000, (recording.twin_position_m[2], None))
    stamp, shapes = frame.take()
    assert stamp == 20_000_000 and frame.take() is None
    feed(frame, recording, 3, 60_000_000)
    frame.on_view('true_pose', 20_000_000, (recording.true_position_m[0], None))  # late, of a drawn tick
    stamp, shapes = frame.take()
    assert stamp == 60_000_000 and frame.take() is None and not frame.ticks
    shapes = {(s.namespace, s.id): s for s in shapes}
    assert np.allclose(shapes['end_effector', 0].points_m, [recording.true_position_m[3]])


def test_the_tension_scale_runs_from_blue_at_the_floor_to_red_at_the_ceiling():
    low, high = 1.0, 100.0
    tensions = np.linspace(-10.0, 120.0, 200)
    colours = tension_colour(tensions, low, high)
    assert np.allclose(colours[tensions <= low], TENSION_SCALE[0])
    assert np.allclose(colours[tensions >= high], TENSION_SCALE[-1])
    assert np.all(np.diff(colours[:, 0]) >= -1e-12) and np.all(np.diff(colours[:, 2]) <= 1e-12)
    assert np.allclose(tension_colour((low + high) / 2, low, high), TENSION_SCALE[1])


def test_a_broken_cable_is_not_drawn_where_the_end_effector_is_found_at_its_exit_height(run):
    """Angles whose lengths no point fits (a loaded realtime graph) place the end-effector
    in the exit points' plane: the broken cable then has no dashes, and no shape (an empty
    one killed the markers node: its colour is its first point's)."""
    scenario = run[0]
    robot = scenario.robot
    position = np.array([0.8, 0.9, robot.exit_points_m[BROKEN - 1, 2]])
    shapes = cable_shapes(robot, scenario.markers, robot.cable_ends_m(position, None),
                          np.full(robot.cable_count, 20.0), [BROKEN])
    assert [shape.id for shape in shapes] == [cable for cable in range(1, robot.cable_count + 1)
                                              if cable != BROKEN]
    assert all(len(shape.points_m) and len(shape.colours) for shape in shapes)


def test_dashes_cover_the_line_with_gaps():
    points = dashes(np.array([0.0, 0.0, 2.0]), np.array([0.0, 0.0, 1.0]), 0.1)
    assert len(points) == 10
    assert np.allclose(points[::2, 2], np.arange(2.0, 1.0, -0.2))
    assert np.allclose(points[1::2, 2] - points[::2, 2], -0.1)


def test_the_safe_point_is_the_supervisors_inside_the_sew_outline_at_its_height(run):
    scenario, recording, frames = run
    identified = recording.fdi['identified_tick']
    placed = 0
    for view, k, shapes in frames:
        if k < identified:
            assert ('safe_point', 0) not in shapes and ('sew_outline', 0) not in shapes
            continue
        placed += 1
        safe_point = shapes['safe_point', 0]
        outline = shapes['sew_outline', 0]
        assert safe_point.kind == SPHERE_LIST and outline.kind == LINE_STRIP
        assert np.allclose(safe_point.points_m, [recording.fdi['safe_point_m']])
        assert np.allclose(outline.points_m[:, 2], scenario.recovery.safe_height_m)
        assert np.allclose(outline.points_m[0], outline.points_m[-1]), 'closed'
        assert contains(outline.points_m[:-1, :2], safe_point.points_m[0, :2])
    assert_judged_once_identified(run, placed)
    # the remaining exit points' projections: cable 4's corner is cut off
    corners = {tuple(p) for p in np.round(outline.points_m[:-1, :2], 9)}
    assert corners == {tuple(p[:2]) for i, p in enumerate(scenario.robot.exit_points_m) if i != BROKEN - 1}


def test_the_recovery_path_is_where_the_end_effector_went_since_the_naming(run):
    scenario, recording, frames = run
    _, _, shapes = frames[-1]
    path = shapes['recovery_path', 0].points_m
    assert len(path) > 10
    assert np.linalg.norm(path[-1] - recording.fdi['safe_point_m']) < scenario.recovery.reached_tolerance_m
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert np.all(steps >= scenario.markers.path_spacing_m - 1e-12)
    identified = recording.fdi['identified_tick']
    named = recording.view_time_s >= identified * scenario.period_s
    # every point a true position of a view tick since the naming, the first the first of them
    assert np.allclose(path[0], recording.true_position_m[named][0])
    assert all(np.min(np.linalg.norm(recording.true_position_m[named] - point, axis=1)) < 1e-12 for point in path)
    assert not any(('recovery_path', 0) in s for _, k, s in frames if k < identified)


def assert_colours(marker, shape) -> None:
    """A marker's colours are the shape's: per point where they differ, else the marker's
    one colour alone (a viewer takes it for every point)."""
    per_point = [[c.r, c.g, c.b, c.a] for c in marker.colors]
    uniform = np.allclose(shape.colours, shape.colours[0])
    assert (per_point == []) == uniform
    assert np.allclose(per_point or [[marker.color.r, marker.color.g, marker.color.b, marker.color.a]] * len(shape.colours),
                       shape.colours, atol=1e-6)


def test_an_inprocess_bag_carries_the_same_markers(run, tmp_path):
    scenario, recording, frames = run
    writer = BagWriter(tmp_path / 'bag')
    writer.open()
    write_recording(writer, recording, frame=scenario.marker_frame())
    writer.close()
    topic = f'{contract.DEFAULT_NAMESPACE}/{contract.MARKERS}'
    messages = [message for _, message in read_messages(tmp_path / 'bag', [topic])[topic]]
    assert len(messages) == len(frames)
    for message, (_, k, shapes) in zip(messages, frames):
        assert message.markers[0].header.stamp.sec * 10 ** 9 + message.markers[0].header.stamp.nanosec \
            == k * 2_000_000, 'stamped with its view tick'
        first, *markers = message.markers
        assert first.action == first.DELETEALL
        assert message.markers[1].header.frame_id == 'world'
        assert {(m.ns, m.id) for m in markers} == set(shapes)
        for m in markers:
            shape = shapes[m.ns, m.id]
            assert m.type == getattr(m, shape.kind) and m.scale.x == shape.scale_m
            assert np.allclose([[p.x, p.y, p.z] for p in m.points], shape.points_m)
            assert_colours(m, shape)
    # as a viewer of MCAP files (Foxglove) decodes them: from the schema the file embeds
    with open(next((tmp_path / 'bag').glob('*.mcap')), 'rb') as file:
        reader = make_reader(file, decoder_factories=[DecoderFactory()])
        viewed = [message for schema, _, _, message in reader.iter_decoded_messages(topics=[topic])
                  if schema.name == 'visualization_msgs/msg/MarkerArray']
    assert len(viewed) == len(frames)
    for message, (_, k, shapes) in zip(viewed, frames):
        assert {(m.ns, m.id) for m in message.markers[1:]} == set(shapes)
        assert {m.header.frame_id for m in message.markers[1:]} == {'world'}


def test_the_node_sends_the_shapes_as_markers(run):
    from visualization_msgs.msg import Marker

    from cdpr_fdi.nodes.markers_node import marker_array
    scenario, _, frames = run
    _, k, shapes = frames[-1]
    message = marker_array(list(shapes.values()), 123)
    assert message.markers[0].action == Marker.DELETEALL
    # one marker per shape, every cable's at least: the pairs below leave none out
    assert len(message.markers) == 1 + len(shapes) > scenario.robot.cable_count
    for m, shape in zip(message.markers[1:], shapes.values()):
        assert (m.ns, m.id, m.type) == (shape.namespace, shape.id, getattr(Marker, shape.kind))
        assert m.header.frame_id == 'world' and m.header.stamp.nanosec == 123
        assert np.allclose([[p.x, p.y, p.z] for p in m.points], shape.points_m)
        assert_colours(m, shape)


def test_a_platforms_safe_pose_is_drawn_as_its_body_over_the_section_it_was_found_on():
    """Cable 5 broken a quarter into the crossed platform's tilting climb (make demo-6dof,
    rigid plant): once named, the safe pose's body (origin to attachment points at the
    safe orientation), its section's points at the safe height, each held by the seven
    cables there, and the recovery path ending at the safe point."""
    from cdpr_control.platform.safe_pose import tension_margin_n
    from cdpr_fdi.recovery_planning.recovery import safe_pose_for
    from conftest import CONFIG_DIR
    scenario = build_scenario(ScenarioOptions(config=str(CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'),
                                              motions=str(CONFIG_DIR / 'crossed_platform_motions.yaml'),
                                              motion='climb-tilt', fail_cables=[5], fail_at_fraction=0.25,
                                              fidelity='rigid'))
    recording = run_inprocess(scenario)
    assert recording.fdi['mode'] == 'SAFE_HOLD'
    frame = scenario.marker_frame()
    identified = recording.fdi['identified_tick']
    shapes = None
    for view, time_s in enumerate(recording.view_time_s):
        k = int(round(time_s / scenario.period_s))
        if k >= identified:
            if not frame.broken_cables:
                assert shapes is not None and ('safe_pose', 0) not in shapes, 'none before the naming'
            frame.on_broken_cable(5)
        feed(frame, recording, view, k * 2_000_000)
        shapes = {(s.namespace, s.id): s for s in frame.take()[1]}
        # the platform's body at its true pose
        assert np.allclose(shapes['platform', 0].points_m[1::2], scenario.robot.cable_ends_m(
            recording.true_position_m[view], recording.true_orientation[view]))
    robot, attached = scenario.robot, scenario.robot.cable_mask([4])
    safe = safe_pose_for(robot, scenario.recovery, attached)
    assert np.allclose(shapes['safe_point', 0].points_m, [recording.fdi['safe_point_m']])
    body = shapes['safe_pose', 0]
    assert body.kind == LINE_LIST
    assert np.allclose(body.points_m[::2], safe.position_m)
    assert np.allclose(body.points_m[1::2], robot.cable_ends_m(safe.position_m, safe.orientation))
    section = shapes['residual_section', 0].points_m
    assert len(section) > 10 and np.allclose(section[:, 2], scenario.recovery.safe_height_m)
    assert all(tension_margin_n(robot, point, safe.orientation, attached) >= 0.0 for point in section[::5])
    path = shapes['recovery_path', 0].points_m
    assert np.linalg.norm(path[-1] - safe.position_m) < scenario.recovery.reached_tolerance_m
    assert ('sew_outline', 0) not in shapes
