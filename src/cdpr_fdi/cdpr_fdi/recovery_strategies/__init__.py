"""Recovery strategies behind one interface (base.py), one module each, chosen per robot
by recovery.strategy (docs/recovery-strategies.md). The paper says other strategies can
be plugged in "without affecting the validity of the FDI algorithm": the supervisor names
the cable, the strategy takes the end-effector from there.

- `paper` (paper.py): the paper's, a tension-space quintic then a move to SP under
  position control; a point mass's.
- `steered` (steered.py): a platform steered to its safe pose under tensions within their
  bounds.
- `braked` (braked.py): a platform braked where it is named and moved to its safe pose
  where the cables left hold it at rest there, steered elsewhere.
- `line` (line.py): the docs' example, a point mass moved straight to SP under position
  control.

`auto`, the default, is the strategy fitting the robot's degrees of freedom (FITTING).

Rooms it may import: detection, recovery_planning.
"""
from __future__ import annotations

from cdpr_control.config import Section
from cdpr_control.model.robot import Robot

from .base import Naming, RecoveryStrategy, StartedRecovery
from .braked import Braked
from .line import Line
from .paper import Paper
from .steered import Steered

STRATEGIES: dict[str, RecoveryStrategy] = {strategy.name: strategy
                                           for strategy in (Paper(), Steered(), Braked(), Line())}
__all__ = ['AUTO', 'FITTING', 'STRATEGIES', 'Naming', 'RecoveryStrategy', 'StartedRecovery', 'configured_strategy']
AUTO = 'auto'
# recovery.strategy `auto`: the strategy of a robot by its degrees of freedom (the shipped
# robots' behaviour before strategies could be chosen)
FITTING = {3: 'paper', 6: 'steered'}


def configured_strategy(recovery: Section, robot: Robot) -> str:
    """The name of the strategy recovery.strategy chooses for `robot` (`auto`: FITTING's);
    ConfigError, naming the key and the file, for one that does not recover the robot's
    degrees of freedom."""
    name = recovery.string('strategy', choices=(AUTO, *STRATEGIES))
    freedom = robot.degrees_of_freedom
    if name == AUTO:
        return FITTING[freedom]
    if STRATEGIES[name].degrees_of_freedom != freedom:
        fitting = [other for other, strategy in STRATEGIES.items() if strategy.degrees_of_freedom == freedom]
        raise recovery.error('strategy', f'is {name}, which recovers a {STRATEGIES[name].degrees_of_freedom}-DOF '
                             f'end-effector, but robot {robot.name}\'s has {freedom} DOF: one of '
                             f'{", ".join([AUTO, *fitting])}')
    return name
