"""What RViz and Foxglove draw of a run (/cdpr/markers), as plain shapes from numpy inputs.

A frame per view tick, from the view topics of that tick (design.md §3) and the verdict:
the cables run from their exit points A_i to the end-effector, coloured by their true
tension on a scale from the robot's tension_min_n (blue) to tension_max_n (red); a broken
cable hangs from its exit point, grey, thin and dashed. The end-effector is the true one
(ground truth); on a real robot, which has none, the cables run to the twin's, uncoloured.
The twin's end-effector, the reference, the safe point, the residual SEW outline at the
safe point's height and the path the end-effector has taken since the naming complete
the picture. A platform's safe pose is drawn as its body there (its origin joined to its
attachment points at the safe orientation), and its residual workspace at the safe
height as the points of the section it was found on (safe_pose.py): a platform's section
need not be convex, so no outline is drawn.

`Frame` gathers the view messages of a run as they come and gives the shapes of each view
tick once that tick's messages are all in; the markers node publishes them, and bag_io
writes them into an in-process run's bag.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.config import Section
from cdpr_control.model.robot import Robot

from ..settings.config import RecoveryConfig
from ..recovery_planning.recovery import RecoveryInfeasible, safe_target

# Every point is in the world frame of docs/design.md §4 (z up).
FRAME_ID = 'world'
# Marker types, as visualization_msgs/Marker names them.
LINE_LIST, LINE_STRIP, SPHERE_LIST = 'LINE_LIST', 'LINE_STRIP', 'SPHERE_LIST'

# RGBA in 0..1. The tension scale runs blue → green → red.
TENSION_SCALE = np.array([[0.1, 0.3, 1.0, 1.0], [0.1, 0.9, 0.2, 1.0], [1.0, 0.1, 0.1, 1.0]])
BROKEN_GREY = (0.55, 0.55, 0.55, 1.0)
END_EFFECTOR_COLOUR = (0.85, 0.85, 0.9, 1.0)
# A cable whose tension is not known (a real robot's: no ground truth).
UNKNOWN_TENSION_COLOUR = (0.7, 0.7, 0.7, 1.0)
REFERENCE_COLOUR = (0.1, 0.1, 0.1, 1.0)
# Half transparent: the twin's ball shows through where it overlaps the robot's.
TWIN_COLOUR = (0.2, 0.6, 1.0, 0.45)
SAFE_POINT_COLOUR = (1.0, 0.8, 0.0, 1.0)
SEW_COLOUR = (0.2, 0.8, 0.3, 1.0)
PATH_COLOUR = (1.0, 0.5, 0.0, 1.0)


@dataclass(frozen=True)
class Shape:
    """One marker: `points_m` (n × 3, world frame) and a colour per point (n × 4 RGBA);
    `scale_m` is a line's width or a sphere's diameter."""
    namespace: str
    id: int
    kind: str
    points_m: np.ndarray
    colours: np.ndarray
    scale_m: float

    @property
    def point_colours(self) -> list:
        """The colour of each point as a marker carries it: none where they are all the
        marker's colour (the first), which a viewer then takes for every point."""
        colours = self.colours.tolist()
        return [] if all(colour == colours[0] for colour in colours) else colours


@dataclass(frozen=True)
class MarkerStyle:
    """The `markers` section (defaults/markers.yaml)."""
    cable_width_m: float
    broken_cable_width_m: float
    dash_length_m: float
    end_effector_diameter_m: float
    reference_diameter_m: float
    safe_point_diameter_m: float
    line_width_m: float
    path_spacing_m: float

    @classmethod
    def from_section(cls, section: Section) -> 'MarkerStyle':
        return cls(**{name: section.number(name, positive=True) for name in cls.__dataclass_fields__})


def tension_colour(tension_n: np.ndarray, tension_min_n: float, tension_max_n: float) -> np.ndarray:
    """RGBA (… × 4) of each tension (N) on the scale from tension_min_n to tension_max_n,
    clipped at its ends: a slack cable is as blue as one at the floor."""
    fraction = np.clip((np.asarray(tension_n, float) - tension_min_n)
                       / (tension_max_n - tension_min_n), 0.0, 1.0)
    position = fraction * (len(TENSION_SCALE) - 1)
    lower = np.minimum(position.astype(int), len(TENSION_SCALE) - 2)
    weight = (position - lower)[..., None]
    return (1.0 - weight) * TENSION_SCALE[lower] + weight * TENSION_SCALE[lower + 1]


def dashes(start_m: np.ndarray, end_m: np.ndarray, dash_length_m: float) -> np.ndarray:
    """The end points (2k × 3) of dashes of `dash_length_m` with gaps as long, from
    `start_m` towards `end_m` (a LINE_LIST)."""
    length = float(np.linalg.norm(end_m - start_m))
    if length == 0.0:
        return np.empty((0, 3))
    starts = np.arange(0.0, length, 2.0 * dash_length_m)
    ends = np.minimum(starts + dash_length_m, length)
    along = np.column_stack([starts, ends]).ravel() / length
    return start_m + along[:, None] * (end_m - start_m)


def _single(namespace: str, kind: str, points_m, colour, scale_m: float, id: int = 0) -> Shape:
    points = np.atleast_2d(np.asarray(points_m, float))
    return Shape(namespace, id, kind, points, np.tile(colour, (len(points), 1)), scale_m)


def cable_shapes(robot: Robot, style: MarkerStyle, ends_m: np.ndarray,
                 tension_n: np.ndarray | None, broken_cables: list[int]) -> list[Shape]:
    """Per cable (id = its 1-based number): a line from its exit point to where it ends on
    the end-effector (`ends_m`, m × 3: Robot.cable_ends_m) coloured by its
    tension (None: unknown, grey), or, for a broken cable, a dashed grey line hanging
    straight down from its exit point to its end's height (none when the end is found at
    that height or above: a marker of no points has nothing to draw, nor a colour)."""
    colours = (np.tile(UNKNOWN_TENSION_COLOUR, (robot.cable_count, 1)) if tension_n is None
               else tension_colour(tension_n, robot.tension_min_n, robot.tension_max_n))
    shapes = []
    for index, (exit_point, end) in enumerate(zip(robot.exit_points_m, ends_m)):
        cable = index + 1
        if cable in broken_cables:
            if end[2] < exit_point[2]:
                below = np.array([exit_point[0], exit_point[1], end[2]])
                shapes.append(_single('cables', LINE_LIST, dashes(exit_point, below, style.dash_length_m),
                                      BROKEN_GREY, style.broken_cable_width_m, cable))
        else:
            shapes.append(_single('cables', LINE_LIST, [exit_point, end], colours[index],
                                  style.cable_width_m, cable))
    return shapes


def platform_body(robot: Robot, position_m, orientation) -> np.ndarray:
    """A platform's body as line pairs (2m × 3, m): its origin joined to each attachment
    point at the pose."""
    ends = robot.cable_ends_m(position_m, orientation)
    return np.array([point for end in ends for point in (position_m, end)])


class Frame:
    """A run's markers as its view messages arrive: per view tick (its stamp, ns) the true
    pose and tensions (`ground_truth`: a simulated run's), the twin's and the reference's
    pose; and the broken cables as named. `take()` gives the shapes of the newest tick
    whose messages are all in (once each; older incomplete ticks are passed over)."""

    def __init__(self, robot: Robot, recovery: RecoveryConfig, style: MarkerStyle, ground_truth: bool = True):
        self.robot = robot
        self.recovery = recovery
        self.style = style
        self.ground_truth = ground_truth
        self.needed = {'twin', 'reference'} | ({'true_pose', 'true_tension'} if ground_truth else set())
        self.broken_cables: list[int] = []
        # stamp ns → what arrived of that view tick: name → value
        self.ticks: dict[int, dict] = {}
        self.drawn_ns = -1
        self.path_m: list[np.ndarray] = []
        self.safe_point_m: np.ndarray | None = None
        self.sew_outline_m: np.ndarray | None = None
        # a platform's: its body at the safe pose (pairs of points) and the section's points
        self.safe_body_m: np.ndarray | None = None
        self.residual_section_m: np.ndarray | None = None

    @property
    def attached(self) -> np.ndarray:
        return self.robot.cable_mask([cable - 1 for cable in self.broken_cables])

    def on_broken_cable(self, cable: int) -> None:
        """fdi/broken_cable: 0 while healthy, then each broken cable (1-based): the safe
        target after the cables broken so far (recovery.safe_target), its residual section,
        and where it has an orientation, the platform's body there; nothing where there is
        none."""
        if cable <= 0 or cable in self.broken_cables:
            return
        self.broken_cables.append(cable)
        self.safe_point_m = self.sew_outline_m = self.safe_body_m = self.residual_section_m = None
        try:
            target = safe_target(self.robot, self.recovery, self.attached)
        except RecoveryInfeasible:
            return
        self.safe_point_m = target.position_m
        self.sew_outline_m, self.residual_section_m = target.outline_m, target.section_points_m
        if target.orientation is not None:
            self.safe_body_m = platform_body(self.robot, target.position_m, target.orientation)

    def on_view(self, name: str, stamp_ns: int, value) -> None:
        """A view message of the tick stamped `stamp_ns`: `name` twin, reference or
        true_pose ((position m, orientation or None)), true_tension (N per cable)."""
        if stamp_ns > self.drawn_ns:
            self.ticks.setdefault(stamp_ns, {})[name] = value

    def take(self) -> tuple[int, list[Shape]] | None:
        """(stamp ns, shapes) of the newest complete view tick not drawn yet; None if none."""
        complete = [stamp for stamp, seen in self.ticks.items() if self.needed <= seen.keys()]
        if not complete:
            return None
        stamp = max(complete)
        seen = self.ticks.pop(stamp)
        self.ticks = {later: value for later, value in self.ticks.items() if later > stamp}
        self.drawn_ns = stamp
        return stamp, self.shapes(seen)

    def shapes(self, seen: dict) -> list[Shape]:
        """The shapes of one view tick's messages."""
        style = self.style
        twin_position, _ = seen['twin']
        position, orientation = seen['true_pose'] if self.ground_truth else seen['twin']
        if self.broken_cables and (not self.path_m or np.linalg.norm(position - self.path_m[-1])
                                   >= style.path_spacing_m):
            self.path_m.append(np.asarray(position, float))
        ends = self.robot.cable_ends_m(position, orientation)
        shapes = cable_shapes(self.robot, style, ends, seen.get('true_tension'), self.broken_cables)
        if self.ground_truth:
            shapes.append(_single('end_effector', SPHERE_LIST, position, END_EFFECTOR_COLOUR,
                                  style.end_effector_diameter_m))
            outline = self.robot.body.outline_m(self.robot, position, orientation)
            if len(outline):
                shapes.append(_single('platform', LINE_LIST, outline, END_EFFECTOR_COLOUR, style.cable_width_m))
        shapes.append(_single('twin', SPHERE_LIST, twin_position, TWIN_COLOUR, style.end_effector_diameter_m))
        shapes.append(_single('reference', SPHERE_LIST, seen['reference'][0], REFERENCE_COLOUR,
                              style.reference_diameter_m))
        if self.safe_point_m is not None:
            shapes.append(_single('safe_point', SPHERE_LIST, self.safe_point_m, SAFE_POINT_COLOUR,
                                  style.safe_point_diameter_m))
        if self.sew_outline_m is not None:
            closed = np.vstack([self.sew_outline_m, self.sew_outline_m[:1]])
            shapes.append(_single('sew_outline', LINE_STRIP, closed, SEW_COLOUR, style.line_width_m))
        if self.safe_body_m is not None:
            shapes.append(_single('safe_pose', LINE_LIST, self.safe_body_m, SAFE_POINT_COLOUR, style.cable_width_m))
        if self.residual_section_m is not None:
            shapes.append(_single('residual_section', SPHERE_LIST, self.residual_section_m, SEW_COLOUR,
                                  style.line_width_m))
        if len(self.path_m) >= 2:
            shapes.append(_single('recovery_path', LINE_STRIP, self.path_m, PATH_COLOUR, style.line_width_m))
        return shapes
