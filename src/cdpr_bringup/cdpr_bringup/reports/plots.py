"""The paper's figures of one run (matplotlib, Agg), drawn from a report.Run: the loop
topics at every tick, the view topics (poses, true tensions) on the view ticks.

Each function writes one PNG and returns its one-line caption, or None when the bag
holds nothing for it. Colours follow the paper: robot red and twin blue (Fig. 4); x, y,
z red, green, blue (Fig. 7); path before the failure red, recovery phase 1 green,
phase 2 blue, nominal dashed (Fig. 6); residual SEW border magenta (Fig. 20).
"""
from __future__ import annotations

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import numpy as np  # noqa: E402

from cdpr_control.geometry.rotation import to_rotation_vector  # noqa: E402
from cdpr_control.point_mass.workspace import sew_cross_section  # noqa: E402
from cdpr_msgs_py.contract import (FAULT, NOMINAL, RECOVERY_MOVE,  # noqa: E402
                                   RECOVERY_TENSION, SAFE_HOLD)

DPI = 120
AXIS_COLOURS = ('tab:red', 'tab:green', 'tab:blue')
PHASES = {  # mode → (colour, legend label) of the path and the time span while in it
    NOMINAL: ('tab:red', 'before the failure'),
    RECOVERY_TENSION: ('tab:green', 'recovery phase 1 (tension space)'),
    RECOVERY_MOVE: ('tab:blue', 'recovery phase 2 (move to SP)'),
    SAFE_HOLD: ('tab:purple', 'safe hold at SP'),
    FAULT: ('tab:gray', 'FAULT (holding what can be held)'),
}
SEW_COLOUR = 'magenta'
# Margins around the axes (inches), fixed rather than measured from the texts: see place_axes.
# They hold 10-pt axis labels and y tick labels of up to six characters (−0.475).
LEFT_IN = 0.85         # y tick labels and a one-line y label
LABEL_LINE_IN = 0.2    # each further line of a y label
RIGHT_IN = 0.25        # half of the last x tick label
BOTTOM_IN = 0.6        # x tick labels and the x label
TITLE_IN = 0.4         # an axes title
ROW_GAP_IN = 0.25      # between rows sharing their x axis: a y offset text (1e−3) fits
EDGE_IN = 0.1          # between the figure's edge and a title or legend
LEGEND_TOP_IN = 0.35   # a figure legend's top below the top edge, under the title
LEGEND_ROW_IN = 0.175  # one row of an 8-pt legend
LEGEND_PAD_IN = 0.1    # the padding around a legend's rows


def motor_rows(run, ylabel: str, unit: str = 'motor'):
    """One axes per motor (or cable), sharing the time axis."""
    m = run.robot.cable_count
    figure, axes = plt.subplots(m, 1, sharex=True, figsize=(10, 1.6 + 1.7 * m), squeeze=False)
    axes = axes[:, 0]
    for i, ax in enumerate(axes):
        ax.set_ylabel(f'{unit} {i + 1}\n{ylabel}')
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel('time (s)')
    return figure, axes


def mark_events(run, axes) -> None:
    """Vertical lines at the failure (black dashed) and the detection (red dash-dot), and
    the supervisor's recovery modes as shaded spans; labelled on the top axes."""
    ends = [t for t, _ in run.modes[1:]] + [run.time_s[-1]]
    for index, ax in enumerate(axes):
        labelled = index == 0
        for (start, mode), end in zip(run.modes, ends):
            if mode != NOMINAL:
                colour, label = PHASES.get(mode, ('tab:gray', mode))
                ax.axvspan(start, end, color=colour, alpha=0.1, lw=0,
                           label=label if labelled else None)
        if run.failure_time_s is not None:
            ax.axvline(run.failure_time_s, color='black', ls='--', lw=1,
                       label='failure' if labelled else None)
        if run.detection_time_s is not None:
            ax.axvline(run.detection_time_s, color='tab:red', ls='-.', lw=1,
                       label='detection' if labelled else None)


def place_axes(figure, left_in: float = LEFT_IN, right_in: float = RIGHT_IN,
               top_in: float = TITLE_IN, bottom_in: float = BOTTOM_IN,
               row_gap_in: float = ROW_GAP_IN, column_gap_in: float = 0.0) -> None:
    """The figure's grid of axes at fixed distances from its edges and from each other
    (inches), so that the texts around the axes keep their room whatever the figure's size
    and number of rows. tight_layout measures every text instead (a third of a figure's
    time) and leaves a layout engine that makes savefig draw the whole figure twice."""
    width_in, height_in = figure.get_size_inches()
    rows, columns = figure.axes[0].get_gridspec().get_geometry()
    left, right = left_in / width_in, 1 - right_in / width_in
    bottom, top = bottom_in / height_in, 1 - top_in / height_in
    figure.subplots_adjust(
        left=left, right=right, bottom=bottom, top=top,
        hspace=gap_fraction(row_gap_in, (top - bottom) * height_in, rows),
        wspace=gap_fraction(column_gap_in, (right - left) * width_in, columns))


def gap_fraction(gap_in: float, span_in: float, count: int) -> float:
    """The gap between `count` axes sharing `span_in` as subplots_adjust takes it: a
    fraction of their mean size."""
    return gap_in * count / (span_in - gap_in * (count - 1))


def legend_height_in(labels: list, columns: int) -> float:
    """Of an 8-pt legend of `labels` in `columns` columns."""
    rows = -(-len(labels) // columns)
    return LEGEND_PAD_IN + rows * LEGEND_ROW_IN


def write(figure, path) -> None:
    # PNG compression level 1 of 9: a third less encoding time than the default 6, for files
    # about 12 % larger
    figure.savefig(path, dpi=DPI, pil_kwargs={'compress_level': 1})
    plt.close(figure)


def save(figure, path, title: str, legend_axes, column_gap_in: float = 0.0) -> None:
    """Title and the legend of `legend_axes` above the axes, so that neither hides a curve;
    columns of axes `column_gap_in` apart."""
    height_in = figure.get_size_inches()[1]
    ylabel_lines = max(ax.get_ylabel().count('\n') + 1 for ax in figure.axes)
    figure.suptitle(title, y=1 - EDGE_IN / height_in, va='top')
    handles, labels = legend_axes.get_legend_handles_labels()
    columns = min(len(labels), 4)
    figure.legend(handles, labels, loc='upper center', ncol=columns, fontsize=8,
                  bbox_to_anchor=(0.5, 1 - LEGEND_TOP_IN / height_in), frameon=False)
    place_axes(figure, left_in=LEFT_IN + (ylabel_lines - 1) * LABEL_LINE_IN,
               top_in=LEGEND_TOP_IN + legend_height_in(labels, columns) + ROW_GAP_IN, column_gap_in=column_gap_in)
    write(figure, path)


def torques(run, path) -> str:
    """Paper Fig. 4/12/8: commanded torque c of the robot vs the twin's c_DT, per motor."""
    recording = run.recording
    figure, axes = motor_rows(run, 'torque (N·m)')
    for i, ax in enumerate(axes):
        ax.plot(recording.time_s, recording.twin_torque_nm[:, i], color='tab:blue', lw=1,
                label='digital twin c_DT')
        ax.plot(recording.time_s, recording.command_nm[:, i], color='tab:red', lw=1,
                label='robot c (/effort_command)')
    mark_events(run, axes)
    save(figure, path, 'Motor torques: robot vs digital twin', axes[0])
    return 'Commanded motor torques of the robot (red) and of the digital twin (blue) per motor.'


def residuals(run, path) -> str:
    """Paper Fig. 15/18: r = c − c_DT per motor against the threshold ±ε."""
    figure, axes = motor_rows(run, 'residual (N·m)')
    for i, ax in enumerate(axes):
        ax.plot(run.time_s, run.residual_nm[:, i], color='tab:purple', lw=1, label='residual r')
        for sign in (1, -1):
            ax.axhline(sign * run.epsilon_nm, color='0.3', ls='--', lw=0.8,
                       label='±ε' if sign > 0 else None)
    mark_events(run, axes)
    save(figure, path, f'Torque residuals r = c − c_DT, threshold ε = {run.epsilon_nm:g} N·m', axes[0])
    return (f'Torque residual per motor with the detection threshold ±ε = {run.epsilon_nm:g} N·m; '
            'dashed: failure, dash-dot: detection.')


def detection(run, path) -> str | None:
    """Paper Fig. 5/14/21: the detection signal (0 or the cable named) vs the failure,
    over the whole run and zoomed on the event."""
    if not run.verdicts:
        return None
    end = run.time_s[-1]
    times = [t for t, _ in run.verdicts] + [end]
    values = [v for _, v in run.verdicts]
    values.append(values[-1])
    figure, axes = plt.subplots(1, 2, figsize=(11, 3.4), gridspec_kw={'width_ratios': [2, 1]})
    broken = run.true_broken_cables[0] if run.true_broken_cables else None
    event = run.event_time_s
    for ax in axes:
        if run.failure_time_s is not None:
            level = broken or max(values)
            # wide and pale beneath the detection signal, which often coincides with it
            ax.step([run.time_s[0], run.failure_time_s, end], [0, level, level], where='post',
                    color='tab:blue', lw=5, alpha=0.4,
                    label=f'failure (cable {broken})' if broken else 'failure')
        ax.step(times, values, where='post', color='tab:red', lw=1.5, label='detection signal')
        ax.set_xlabel('time (s)')
        ax.set_yticks(range(run.robot.cable_count + 1))
        ax.set_ylim(-0.3, run.robot.cable_count + 0.3)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel('broken cable (0 = healthy)')
    axes[0].set_title('Detection signal /fdi/broken_cable')
    if event is not None:
        detected = run.detection_time_s
        span = max(abs(detected - event) if detected is not None else 0.0, 0.02)
        axes[1].set_xlim(event - 1.5 * span, event + 2.5 * span)
        if detected is None:
            delay = 'no detection'
        elif run.failure_time_s is None:
            delay = 'failure time unknown'
        else:
            delay = f'delay {1000 * (detected - run.failure_time_s):.1f} ms'
        axes[1].set_title(f'zoom on the event: {delay}')
    else:
        axes[1].set_visible(False)
    axes[0].legend(loc='upper left', fontsize=8)
    # room between the two for the zoom's y tick labels and the whole run's last x tick label
    place_axes(figure, column_gap_in=0.45)
    write(figure, path)
    return ('Detection signal (red, the cable named or 0) against the failure (blue); '
            'right: zoom on the event.')


def position(run, path) -> str:
    """Paper Fig. 7/22: x, y, z of the end-effector vs time (measured, twin, reference),
    with the failure, the detection and the recovery phases; beside them, for a platform,
    its orientation as the rotation vector φ from the world's axes (deg)."""
    recording = run.recording
    turned = run.orientation is not None
    figure, axes = plt.subplots(3, 2 if turned else 1, sharex=True, figsize=(15 if turned else 10, 7.5),
                                squeeze=False)
    series = [(recording.twin_position_m, recording.reference_position_m, run.position_m, 'm', '')]
    if turned:
        series.append(tuple(np.degrees(to_rotation_vector(orientation)) for orientation in (
            recording.twin_orientation, recording.reference_orientation, run.orientation)) + ('°', 'φ'))
    for column, (twin, reference, robot, unit, name) in enumerate(series):
        for axis, ax in enumerate(axes[:, column]):
            colour = AXIS_COLOURS[axis]
            ax.plot(recording.view_time_s, twin[:, axis], color=colour, alpha=0.45, lw=3, label='digital twin')
            ax.plot(recording.view_time_s, reference[:, axis], color='black', ls='--', lw=1, label='reference')
            ax.plot(run.pose_time_s, robot[:, axis], color=colour, lw=1.2, label=run.position_label)
            ax.set_ylabel(f'{name}{"xyz"[axis]} ({unit})')
            ax.grid(alpha=0.3)
        axes[-1, column].set_xlabel('time (s)')
        mark_events(run, axes[:, column])
    save(figure, path, 'End-effector pose' if turned else 'End-effector coordinates', axes[0, 0],
         column_gap_in=LEFT_IN + LABEL_LINE_IN if turned else 0.0)
    return (f'End-effector x (red), y (green), z (blue)'
            + (', and beside them its orientation as the rotation vector φ from the world\'s axes (deg)'
               if turned else '')
            + f': {run.position_label} (thin), digital twin (wide, pale), reference (dashed); failure, '
            'detection and recovery phases marked.')


def phase_segments(run):
    """(colour, label, mask of `run.pose_time_s`) of the path's pieces: by the supervisor's
    mode once it left NOMINAL, else before / after the failure."""
    time_s = run.pose_time_s
    if any(mode != NOMINAL for _, mode in run.modes):
        starts = [-np.inf] + [t for t, _ in run.modes[1:]] + [np.inf]
        for (_, mode), start, end in zip(run.modes, starts, starts[1:]):
            colour, label = PHASES.get(mode, ('tab:gray', mode))
            # each piece runs into the next so that the path has no gaps
            yield colour, label, (time_s >= start) & (time_s <= end + 1e-9)
    elif run.event_time_s is not None:
        yield PHASES[NOMINAL][0], PHASES[NOMINAL][1], time_s <= run.event_time_s
        yield 'tab:orange', 'after the failure (no recovery)', time_s >= run.event_time_s
    else:
        yield 'tab:red', run.position_label, np.ones(time_s.size, dtype=bool)


def draw_paths(run, ax, project) -> None:
    """Reference, twin when nothing failed, and the phase-coloured path, on `ax`."""
    recording = run.recording
    ax.plot(*project(recording.reference_position_m), color='black', ls='--', lw=1,
            label='nominal (reference)')
    if not run.broken_cables:
        ax.plot(*project(recording.twin_position_m), color='tab:green', lw=1, label='digital twin')
    labelled = set()
    for colour, label, mask in phase_segments(run):
        if mask.any():
            ax.plot(*project(run.position_m[mask]), color=colour, lw=1.5,
                    label=None if label in labelled else label)
            labelled.add(label)


def safe_border(run):
    """The residual SEW border at the safe point's height (closed polygon, k × 2), or None."""
    if run.safe_point_m is None:
        return None
    border = sew_cross_section(run.robot, run.attached, run.safe_point_m[2])
    return np.vstack([border, border[:1]])


def mark_failure(run, ax, project) -> None:
    """A circle where the end-effector was when the cable broke (paper Fig. 13/16)."""
    if run.event_time_s is not None:
        tick = min(np.searchsorted(run.pose_time_s, run.event_time_s), run.pose_time_s.size - 1)
        ax.scatter(*project(run.position_m[tick:tick + 1]), s=60, facecolor='none',
                   edgecolor='black', lw=1.5, label='failure point', zorder=5)


def path_3d(run, path) -> str:
    """Paper Fig. 6/19 (Fig. 10 without a failure): the end-effector's path in space."""
    figure = plt.figure(figsize=(8, 7))
    ax = figure.add_subplot(projection='3d')
    project = lambda p: (p[:, 0], p[:, 1], p[:, 2])  # noqa: E731
    draw_paths(run, ax, project)
    mark_failure(run, ax, project)
    shown = [run.position_m, run.recording.reference_position_m]
    if run.safe_point_m is not None:
        ax.scatter(*run.safe_point_m, marker='*', s=150, color='gold', edgecolor='black',
                   label='safe point SP', zorder=5)
        shown.append(run.safe_point_m[None, :])
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_zlabel('z (m)')
    points = np.vstack(shown)
    low, high = points.min(axis=0), points.max(axis=0)
    # one scale on the three axes (a cube), so that the path keeps its shape and a
    # planar motion's sub-millimetre wobble is not blown up into waves
    centre, half = (low + high) / 2.0, 0.55 * np.max(high - low)
    for set_limits, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        set_limits(c - half, c + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.legend(loc='upper left', fontsize=8)
    ax.set_title('End-effector path')
    # the cube fills its place, its tick and axis labels overhang it below and on the right
    place_axes(figure, left_in=0.0, right_in=0.3, bottom_in=0.3)
    write(figure, path)
    if run.broken_cables:
        return ('End-effector path in space: before the failure (red), recovery phase 1 (green), '
                'phase 2 (blue), nominal dashed, SP (star).')
    return 'End-effector path in space against the nominal (dashed) path and the twin\'s.'


def path_top(run, path) -> str:
    """Paper Fig. 20: the path seen from above, in the robot's frame, with the residual
    SEW border and the safe point after a failure."""
    figure, ax = plt.subplots(figsize=(7, 7.5))
    exits = run.robot.exit_points_m
    ax.scatter(exits[:, 0], exits[:, 1], marker='^', color='black', label='exit points A_i')
    for i, (x, y, _) in enumerate(exits):
        ax.annotate(f'A{i + 1}', (x, y), xytext=(4, 4), textcoords='offset points')
    project = lambda p: (p[:, 0], p[:, 1])  # noqa: E731
    draw_paths(run, ax, project)
    mark_failure(run, ax, project)
    border = safe_border(run)
    if border is not None:
        ax.plot(border[:, 0], border[:, 1], color=SEW_COLOUR, lw=1.5,
                label=f'residual SEW border at z = {run.safe_point_m[2]:.2f} m')
        ax.scatter(*run.safe_point_m[:2], marker='*', s=200, color='gold', edgecolor='black',
                   label=f'SP = ({run.safe_point_m[0]:.2f}, {run.safe_point_m[1]:.2f}, '
                         f'{run.safe_point_m[2]:.2f}) m', zorder=5)
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_aspect('equal')
    ax.grid(alpha=0.3)
    ax.set_title('End-effector path, top view')
    handles, labels = ax.get_legend_handles_labels()
    columns = 2
    place_axes(figure, bottom_in=EDGE_IN + legend_height_in(labels, columns) + BOTTOM_IN)
    # the equal aspect narrows or lowers the axes within its place: on its place's bottom,
    # it stays on the legend below, which is centred under it
    ax.set_anchor('S')
    place = figure.subplotpars
    figure.legend(handles, labels, loc='lower center', ncol=columns, fontsize=8,
                  bbox_to_anchor=((place.left + place.right) / 2,
                                  EDGE_IN / figure.get_size_inches()[1]))
    write(figure, path)
    return 'Top view of the path in the frame of the exit points' + (
        ', with the residual SEW border (magenta) and SP.' if border is not None else '.')


def tensions(run, path) -> str:
    """Cable tensions: the sensorless estimate τ̂ = (J θ̈ + b θ̇ + f_c − c)/ρ, and the truth
    in simulation."""
    times, estimate = run.tension_estimate_n
    figure, axes = motor_rows(run, 'tension (N)', unit='cable')
    for i, ax in enumerate(axes):
        if run.has_ground_truth:
            ax.plot(run.recording.view_time_s, run.recording.true_tension_n[:, i], color='black', lw=2.5,
                    alpha=0.35, label='true (ground truth)')
        ax.plot(times, estimate[:, i], color='tab:orange', lw=0.8, label='sensorless estimate τ̂')
        ax.axhline(0.0, color='0.5', lw=0.8)
    mark_events(run, axes)
    save(figure, path, 'Cable tensions', axes[0])
    return (f'Cable tensions estimated from the motors alone (orange; Coulomb friction '
            f'{run.friction.coulomb_nm:g} N·m assumed)'
            + (' and the true ones (grey).' if run.has_ground_truth else '.'))


FIGURES = {
    'torques': torques,
    'residuals': residuals,
    'detection': detection,
    'position': position,
    'path_3d': path_3d,
    'path_top': path_top,
    'tensions': tensions,
}
