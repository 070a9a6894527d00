"""The topic contract of docs/design.md §3: names (relative to the namespace) and modes."""
from __future__ import annotations

DEFAULT_NAMESPACE = '/cdpr'

JOINT_STATES = 'joint_states'
REFERENCE = 'reference'
REFERENCE_POSE = 'reference/pose'
GOAL = 'goal'
EFFORT_COMMAND = 'effort_command'
TWIN_JOINT_STATES = 'twin/joint_states'
TWIN_POSE = 'twin/pose'
FDI_RESIDUAL = 'fdi/residual'
FDI_BROKEN_CABLE = 'fdi/broken_cable'
MODE = 'mode'
RECOVERY_TENSIONS = 'recovery/tensions'
RECOVERY_REFERENCE = 'recovery/reference'
GROUND_TRUTH_POSE = 'ground_truth/pose'
GROUND_TRUTH_TENSIONS = 'ground_truth/tensions'
INJECT_FAILURE = 'inject_failure'
CLOCK = '/clock'
DIAGNOSTICS = '/diagnostics'

# Topics that late joiners must still see: reliable + transient-local.
LATCHED_TOPICS = (FDI_BROKEN_CABLE, MODE)


# What the controller is doing, published on `mode` by the supervisor: the one
# definition of the mode names (the controller core and the health rules import them).
NOMINAL = 'NOMINAL'
RECOVERY_TENSION = 'RECOVERY_TENSION'
RECOVERY_MOVE = 'RECOVERY_MOVE'
SAFE_HOLD = 'SAFE_HOLD'
FAULT = 'FAULT'
MODES = (NOMINAL, RECOVERY_TENSION, RECOVERY_MOVE, SAFE_HOLD, FAULT)


def joint_names(cable_count: int) -> list[str]:
    """motor_1 … motor_m, the joint order everywhere."""
    return [f'motor_{i + 1}' for i in range(cable_count)]
