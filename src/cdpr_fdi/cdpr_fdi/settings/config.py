"""FDI and recovery settings from the robot YAML (`fdi`, `recovery`) and a calibration file.

A calibration file written by `cdpr-calibrate` holds an `fdi` mapping with the same keys
as the robot file's; its values replace the robot file's. The motors' Coulomb friction
is robot.motor.static_friction_nm unless `fdi.coulomb_friction_nm` (e.g. as calibrated
from failure-free runs) says otherwise.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cdpr_control.config import Section, load_config, load_section, load_yaml, with_defaults
from cdpr_control.model.friction import FrictionModel
from cdpr_control.model.robot import Robot
from cdpr_control.platform.steered_approach import ApproachGains
from cdpr_control.geometry.trajectories import QUINTIC_PEAK_SPEED_RATIO

from ..detectors import DETECTORS
from ..recovery_strategies import STRATEGIES, configured_strategy


@dataclass(frozen=True)
class FdiConfig:
    detector: str
    epsilon_nm: float
    delta_nm: float
    friction: FrictionModel
    cusum_sigma_nm: tuple[float, ...]
    cusum_drift: float
    cusum_threshold: float
    cusum_limit: float
    cusum_epsilon_nm: float
    late_command_guard_cycles: int
    late_command_burst: int
    late_command_window_cycles: int
    identification_confirm_cycles: int
    identification_freed_lead_cycles: int
    identification_window_cycles: int
    collapse_window_cycles: int
    collapse_band_n: float
    collapse_reference_n: float
    disturbance_force_n: float
    disturbance_window_cycles: int
    disturbance_hold_cycles: int
    disturbance_settle_cycles: int
    identification_stretch_m: float
    identification_lead_stretch_m: float
    drive_delay_s: float
    # the friction the twin models itself (FrictionModel.of_twin; None for none): of the
    # motors' Coulomb friction (`friction`) the residual shows only the rest
    twin_friction: FrictionModel | None = None

    @property
    def residual_friction(self) -> FrictionModel:
        """The Coulomb friction the residual shows: the motors' beyond the twin's."""
        modelled = 0.0 if self.twin_friction is None else self.twin_friction.coulomb_nm
        return dataclasses.replace(self.friction, coulomb_nm=max(self.friction.coulomb_nm - modelled, 0.0))

    @classmethod
    def from_section(cls, fdi: Section, robot: Robot, friction: FrictionModel,
                     twin_friction: FrictionModel | None = None) -> 'FdiConfig':
        cusum = fdi.section('cusum')
        sigma = cusum.per_cable('sigma_nm', robot.cable_count, positive=True)
        return cls(
            detector=fdi.string('detector', choices=DETECTORS),
            epsilon_nm=fdi.number('epsilon_nm', positive=True),
            # a tolerance on the cable's tension, felt at the motor through its drum
            delta_nm=robot.motor.drum_radius_m * identification_delta_n(fdi, robot),
            friction=(FrictionModel(fdi.number('coulomb_friction_nm', non_negative=True),
                                    friction.smoothing_rad_s)
                      if fdi.has('coulomb_friction_nm') else friction),
            cusum_sigma_nm=tuple(sigma.tolist()),
            cusum_drift=cusum.number('drift', non_negative=True),
            cusum_threshold=cusum.number('threshold', positive=True),
            cusum_limit=cusum.number('limit', positive=True),
            cusum_epsilon_nm=cusum.number('epsilon_nm', positive=True),
            late_command_guard_cycles=fdi.integer('late_command_guard_cycles', minimum=0),
            late_command_burst=fdi.integer('late_command_burst', minimum=1),
            late_command_window_cycles=fdi.integer('late_command_window_cycles', minimum=1),
            identification_confirm_cycles=fdi.integer('identification_confirm_cycles', minimum=1),
            identification_freed_lead_cycles=fdi.integer('identification_freed_lead_cycles', minimum=1),
            identification_window_cycles=fdi.integer('identification_window_cycles', minimum=1),
            collapse_window_cycles=fdi.integer('collapse_window_cycles', minimum=1),
            # both in proportion to the least tension the robot keeps its cables at
            collapse_band_n=fdi.number('collapse_band_share', non_negative=True) * robot.tension_min_n,
            collapse_reference_n=fdi.number('collapse_reference_share', positive=True)
            * robot.tension_min_n,
            disturbance_force_n=fdi.number('disturbance_force_n', positive=True),
            disturbance_window_cycles=fdi.integer('disturbance_window_cycles', minimum=1),
            disturbance_hold_cycles=fdi.integer('disturbance_hold_cycles', minimum=1),
            disturbance_settle_cycles=fdi.integer('disturbance_settle_cycles', minimum=0),
            identification_stretch_m=fdi.number('identification_stretch_m', positive=True),
            identification_lead_stretch_m=fdi.number('identification_lead_stretch_m', positive=True),
            drive_delay_s=fdi.number('drive_delay_s', non_negative=True),
            twin_friction=twin_friction,
        )

    def watching(self) -> 'FdiConfig':
        """The same settings with every alarm out of reach: a supervisor on them watches a
        failure-free run and says what its tests saw (cdpr-calibrate), acting on nothing."""
        return dataclasses.replace(self, detector='threshold', epsilon_nm=np.inf, collapse_reference_n=np.inf)

    def with_overrides(self, detector: str | None = None, epsilon_nm: float | None = None,
                       coulomb_friction_nm: float | None = None) -> 'FdiConfig':
        """The same settings with the given ones replaced (CLI and ROS parameters)."""
        changes = {}
        if detector:
            if detector not in DETECTORS:
                raise ValueError(f'unknown detector {detector!r}; one of {", ".join(DETECTORS)}')
            changes['detector'] = detector
        if epsilon_nm is not None:
            if epsilon_nm <= 0.0:
                raise ValueError(f'epsilon must be positive, got {epsilon_nm}')
            changes['epsilon_nm'] = float(epsilon_nm)
        if coulomb_friction_nm is not None:
            changes['friction'] = dataclasses.replace(self.friction, coulomb_nm=float(coulomb_friction_nm))
        return dataclasses.replace(self, **changes)


def identification_delta_n(fdi: Section, robot: Robot) -> float:
    """δ (N): `identification_delta_n`, at most `identification_delta_weight_share` of an
    equal share of the end-effector's weight per cable."""
    share = np.linalg.norm(robot.weight_wrench_n) / robot.cable_count
    return min(fdi.number('identification_delta_n', positive=True),
               fdi.number('identification_delta_weight_share', positive=True) * share)


def calibrated_fdi(fdi: Section, robot: Robot, calibration: Section | None) -> Section:
    """A robot file's `fdi` section with a calibration file's values on top (`calibration`:
    the file, read once by the caller; checked to be made on this robot)."""
    if calibration is None:
        return fdi
    check_calibration_robot(calibration, robot, fdi.path)
    # the calibration's values, the robot file's where it has none
    data, _ = with_defaults(dict(calibration.section('fdi').data), fdi.data)
    return Section(data, calibration.path, 'fdi')


def load_fdi_config(config_path: str | Path, robot: Robot,
                    calibration_path: str | Path | None = None) -> FdiConfig:
    """The robot file's `fdi` section, with a calibration file's values on top."""
    config = load_config(config_path)
    friction = FrictionModel.of_robot(robot, config.section('control'))
    calibration = None if not calibration_path else Section(load_yaml(calibration_path), calibration_path)
    return FdiConfig.from_section(calibrated_fdi(config.section('fdi'), robot, calibration),
                                  robot, friction, FrictionModel.of_twin(config.section('twin'), config.section('control')))


def check_calibration_robot(calibration: Section, robot: Robot, config_path: str | Path) -> None:
    """ConfigError unless the calibration file was made on this robot (its
    `calibration.robot_fingerprint` is Robot.fingerprint()): thresholds measured on
    another robot's noise and friction miss its failures or raise false alarms."""
    made_on = calibration.section('calibration')
    fingerprint = made_on.string('robot_fingerprint')
    if fingerprint != robot.fingerprint():
        raise made_on.error(
            'robot_fingerprint', f'is {fingerprint} (robot {made_on.string("robot", "?")}), but '
            f'{config_path} describes robot {robot.name}, {robot.fingerprint()}: make its own with '
            f'cdpr-calibrate --config {config_path} --motions MOTIONS.yaml --out FILE')


@dataclass(frozen=True)
class RecoveryConfig:
    """Paper §3.2: where to go after a failure and how (heights m, times s, speeds)."""

    safe_height_m: float
    table_height_m: float
    safe_points_m: dict[int, np.ndarray]
    tension_phase_s: float
    taut_fraction: float
    settle_speed_m_s: float
    settle_timeout_s: float
    move_peak_speed_m_s: float
    brake_deceleration_m_s2: float
    minimum_move_s: float
    plan_tension_margin_n: float
    replan_attempts: int
    replan_slowdown: float
    replan_interval_s: float
    command_step_share: float
    brake_lift_m_s2: float
    committed_brake_s: float
    reached_tolerance_m: float
    reached_tolerance_deg: float
    hold_settle_s: float
    hold_replan_attempts: int
    kinematics_fallback_iterations: int
    hold_after_s: float
    swing_damping_ratio: float
    safe_pose_turns_deg: tuple[float, ...]
    safe_pose_grid_m: float
    # the name of the recovery strategy (recovery_strategies/), `auto` resolved
    strategy: str
    approach_gains: ApproachGains
    approach_tension_margin_n: float
    approach_safe_margin_share: float
    approach_turn_limit_deg: float
    approach_limit_s: float
    approach_arrival_m: float
    approach_arrival_deg: float

    def brake_s(self, speed_m_s: float) -> float:
        """How long phase 2 takes to bring an end-effector moving at `speed_m_s` to rest."""
        return max(QUINTIC_PEAK_SPEED_RATIO * speed_m_s / self.brake_deceleration_m_s2,
                   self.minimum_move_s)

    def move_s(self, distance_m: float) -> float:
        """How long phase 2 takes to move `distance_m` to SP from rest, as first planned."""
        return max(QUINTIC_PEAK_SPEED_RATIO * distance_m / self.move_peak_speed_m_s,
                   self.minimum_move_s)

    def budget_s(self, position_m, velocity_m_s, safe_point_m, workspace_m) -> float:
        """The longest a recovery may take (s) from the failure of a robot whose end-effector
        is at `position_m` moving at `velocity_m_s`: the tension phase and its settle time
        (the case outside the residual workspace), braking, the move to SP re-planned
        `replan_attempts` times (each `replan_slowdown` times longer), and the hold that
        shows SP is kept; where the strategy may steer (RecoveryStrategy.steers), its
        approach's limit where that is longer. The move is taken from the corner of the
        workspace box (`workspace_m`: its least and greatest corners, m) farthest from SP
        where that is farther than where the brake would leave the end-effector: phase 1
        holds it by tension alone, and a light one drifts (half a metre up on a 0.8 kg
        end-effector under 2 m cables). A run ends sooner when its recovery does
        (cdpr_twin.nodes.run_length)."""
        brake = self.brake_s(float(np.linalg.norm(velocity_m_s)))
        rest = np.asarray(position_m) + 0.5 * brake * np.asarray(velocity_m_s)
        low, high = (np.asarray(corner, dtype=float) for corner in workspace_m)
        farthest = np.maximum(np.abs(np.asarray(safe_point_m) - low), np.abs(high - np.asarray(safe_point_m)))
        move = self.move_s(max(float(np.linalg.norm(np.asarray(safe_point_m) - rest)),
                               float(np.linalg.norm(farthest))))
        slowest_move = move * self.replan_slowdown ** self.replan_attempts
        # a move that ended off the safe pose: held to settle (no re-plan is scheduled for)
        braked = self.tension_phase_s + self.settle_timeout_s + brake + slowest_move + self.hold_settle_s
        return (max(braked, self.approach_limit_s) if STRATEGIES[self.strategy].steers else braked) + self.hold_after_s

    @classmethod
    def from_section(cls, recovery: Section, robot: Robot) -> 'RecoveryConfig':
        if recovery.has('platform_recovery'):
            # an older file's choice would otherwise be dropped without a word
            raise recovery.error('platform_recovery', 'is gone: recovery.strategy chooses the recovery '
                                 '(steered or braked for a platform)')
        table_height = recovery.number('table_height_m', non_negative=True)
        # SP is clear of the table, inside the workspace
        safe_height = recovery.number('safe_height_m', positive=True, maximum=robot.workspace_max_m[2])
        if safe_height <= table_height:
            raise recovery.error('safe_height_m', f'must be above table_height_m ({table_height:g} m), '
                                 f'got {safe_height!r}')
        overrides = recovery.section('safe_points_m', {})
        safe_points = {}
        for cable in overrides.data:
            # an int in YAML; its digits as a ROS parameter name
            number = int(cable) if isinstance(cable, str) and cable.isdigit() else cable
            if not isinstance(number, int) or not 1 <= number <= robot.cable_count:
                raise overrides.error(str(cable), f'must be a cable number 1..{robot.cable_count}')
            safe_points[number] = overrides.vector(cable, 3)
            point = safe_points[number]
            if (np.any(point < robot.workspace_min_m) or np.any(point > robot.workspace_max_m)
                    or point[2] <= table_height):
                raise overrides.error(str(cable), f'must lie inside the workspace, above table_height_m '
                                      f'({table_height:g} m), got {point.tolist()}')
        turns = recovery.numbers('safe_pose_turns_deg')
        if np.any(turns <= 0.0) or np.any(turns >= 90.0):
            raise recovery.error('safe_pose_turns_deg', f'must be angles in (0, 90) deg, got {turns.tolist()}')
        return cls(
            safe_height_m=safe_height,
            table_height_m=table_height,
            safe_points_m=safe_points,
            tension_phase_s=recovery.number('tension_phase_s', positive=True),
            taut_fraction=recovery.number('taut_fraction', positive=True),
            settle_speed_m_s=recovery.number('settle_speed_m_s', positive=True),
            settle_timeout_s=recovery.number('settle_timeout_s', positive=True),
            move_peak_speed_m_s=recovery.number('move_peak_speed_m_s', positive=True),
            brake_deceleration_m_s2=recovery.number('brake_deceleration_m_s2', positive=True),
            minimum_move_s=recovery.number('minimum_move_s', positive=True),
            # in proportion to the least tension the robot keeps its cables at
            plan_tension_margin_n=recovery.number('plan_tension_margin_share', non_negative=True)
            * robot.tension_min_n,
            replan_attempts=recovery.integer('replan_attempts', minimum=0),
            # each re-plan slower than the one before
            replan_slowdown=recovery.number('replan_slowdown', minimum=1.0),
            replan_interval_s=recovery.number('replan_interval_s', positive=True),
            command_step_share=recovery.number('command_step_share', positive=True, maximum=1.0),
            brake_lift_m_s2=recovery.number('brake_lift_m_s2', non_negative=True),
            committed_brake_s=recovery.number('committed_brake_s', non_negative=True),
            reached_tolerance_m=recovery.number('reached_tolerance_m', positive=True),
            reached_tolerance_deg=recovery.number('reached_tolerance_deg', positive=True, maximum=180.0),
            hold_settle_s=recovery.number('hold_settle_s', non_negative=True),
            hold_replan_attempts=recovery.integer('hold_replan_attempts', minimum=0),
            kinematics_fallback_iterations=recovery.integer('kinematics_fallback_iterations', minimum=1),
            hold_after_s=recovery.number('hold_after_s', non_negative=True),
            swing_damping_ratio=recovery.number('swing_damping_ratio', non_negative=True),
            safe_pose_turns_deg=tuple(turns.tolist()),
            safe_pose_grid_m=recovery.number('safe_pose_grid_m', positive=True),
            strategy=configured_strategy(recovery, robot),
            approach_gains=ApproachGains(
                position_frequency_rad_s=recovery.number('approach_frequency_rad_s', positive=True),
                orientation_frequency_rad_s=recovery.number('approach_turn_frequency_rad_s', positive=True),
                moment_weight=recovery.number('approach_moment_weight', positive=True),
                ease_in_s=recovery.number('approach_ease_in_s', non_negative=True),
                aim_samples=recovery.integer('approach_aim_samples', minimum=2)),
            approach_tension_margin_n=recovery.number('approach_tension_margin_share', non_negative=True)
            * robot.tension_min_n,
            approach_safe_margin_share=recovery.number('approach_safe_margin_share', non_negative=True, maximum=1.0),
            approach_turn_limit_deg=recovery.number('approach_turn_limit_deg', positive=True, maximum=180.0),
            approach_limit_s=recovery.number('approach_limit_s', positive=True),
            approach_arrival_m=recovery.number('approach_arrival_m', positive=True),
            approach_arrival_deg=recovery.number('approach_arrival_deg', positive=True),
        )


def load_recovery_config(config_path: str | Path, robot: Robot) -> RecoveryConfig:
    return RecoveryConfig.from_section(load_section(config_path, 'recovery'), robot)


def settled_fdi(settings, robot: Robot, twin: Section | None = None) -> tuple[FdiConfig, RecoveryConfig]:
    """The FDI and recovery settings of a settled run (`settings`: its document, with a
    `section(name)` as cdpr_control.config.Section's): its `fdi` and `recovery` sections,
    the friction its `control` section settled, and the friction the twin models (its
    `twin` section, as the caller read it where given)."""
    friction = FrictionModel.of_robot(robot, settings.section('control'))
    return (FdiConfig.from_section(settings.section('fdi'), robot, friction,
                                   FrictionModel.of_twin(twin or settings.section('twin'), settings.section('control'))),
            RecoveryConfig.from_section(settings.section('recovery'), robot))
