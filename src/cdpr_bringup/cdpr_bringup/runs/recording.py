"""What a run produced: one row per control tick of the loop topics, one per view tick of
the view topics (design.md §3, "What a tick delivers"), and the figures the node holding
the truth computed from every tick: the in-process engine's output, and what a bag of the
graph (with the nodes' last statuses beside it) reads back as."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Recording:
    """What a run produced (SI units): the loop topics' rows, one per control tick
    (`time_s`), and the view topics' rows, one per view tick (`view_time_s`: the twin's,
    the reference's and the true pose, the true tensions)."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    command_nm: np.ndarray
    twin_angle_rad: np.ndarray
    twin_angular_velocity_rad_s: np.ndarray
    twin_torque_nm: np.ndarray
    reference_angle_rad: np.ndarray
    view_time_s: np.ndarray
    twin_position_m: np.ndarray
    reference_position_m: np.ndarray
    true_position_m: np.ndarray
    true_tension_n: np.ndarray
    residual_nm: np.ndarray | None = None
    # The supervisor's recovery/reference angles published at each tick (for the next),
    # NaN where it published none; None when unknown (a bag's Recording).
    recovery_reference_angle_rad: np.ndarray | None = None
    fdi: dict = field(default_factory=dict)
    # Ctrl-C ended the run early: the rows are the cycles that ran.
    interrupted: bool = False
    # 0-based cable → the instant (s) the plant really parted it, which the field plant's
    # electromagnet makes later than the failure it was told (a simulation's ground
    # truth; None when unknown, as in a bag).
    broken_at_s: dict[int, float] | None = None
    # The ticks each per-tick topic lacks in a bag: its recorder's count
    # (bag_io.missing_ticks), or more where the plant's own count of states says so
    # (metrics.missing_against_the_plant); None where nothing was counted (an in-process
    # run loses nothing).
    missing_ticks: dict[str, int] | None = None
    # A bag's: per topic read (relative name), how many ticks it holds.
    ticks_held: dict[str, int] | None = None
    # The figures of the end-effector from every tick (cdpr_twin.models.run_figures: the summary
    # of RunFigures), as the plant simulator said them in its last status or the in-process
    # engine computed them; None: unknown (a bag without the plant's status).
    figures: dict | None = None
    # A platform's orientations (unit quaternions, a row per view tick): the plant's true
    # one, the twin's and the reference's; None for a point mass.
    true_orientation: np.ndarray | None = None
    twin_orientation: np.ndarray | None = None
    reference_orientation: np.ndarray | None = None

    @property
    def has_ground_truth(self) -> bool:
        """Whether the plant's true pose was recorded on every view tick (only a simulated
        run has it: a bag of the real robot reads back NaN there)."""
        return bool(self.true_position_m.size) and bool(np.isfinite(self.true_position_m).all())


def holes_said(missing: dict[str, int] | None) -> str:
    """One line on what a bag lacks: '' when its recorder counted no tick missing."""
    holes = {topic: count for topic, count in (missing or {}).items() if count}
    if not holes:
        return ''
    return ('the bag lacks ticks (its recorder lost them): '
            + ', '.join(f'{topic} {count}' for topic, count in holes.items())
            + '; figures drawn from the bag are of the ticks it holds')
