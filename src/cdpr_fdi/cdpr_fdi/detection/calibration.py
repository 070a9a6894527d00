"""Detector thresholds from failure-free residuals, for a target false-alarm rate.

A detector alarms when its statistic's maximum over a run exceeds its threshold. The
maxima of the statistic over blocks of W seconds follow, for light tails, a Gumbel law;
fitted to the calibration runs' maxima (each run a block: one whole motion, from rest
to rest, so the blocks are alike), it gives the level a run exceeds with probability
rate · W, i.e. once per 1 / rate hours of such motion. A threshold the calibration data
itself crosses is never returned: the largest value seen bounds it from below.

The tension-collapse test (tension_collapse.py) alarms where a motor reads free while the
reference asks at least its floor of it. Most failure-free runs never read a loaded motor
as free; on a robot with more cables than degrees of freedom some do, where the joints'
position control, not the plan, shares the load (a drawn 7-cable point mass: 0.5 N on a
cable planned at 1.95 N). The floor is set as ε is, on the runs that did, their τ̂ taken with
the friction fitted first (the robot file's break-away friction, 0.1 N·m on the tall
frame's 15 mm drums against 0.049 fitted, would put τ̂ 3.4 N off).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.model.friction import FrictionModel

EULER_GAMMA = 0.5772156649015329


@dataclass
class FailureFreeRun:
    """Per tick of one failure-free run: residual r (N·m) and the twin's θ̇ (rad/s)."""

    residual_nm: np.ndarray
    twin_angular_velocity_rad_s: np.ndarray


def fit_coulomb_friction(runs: list[FailureFreeRun], smoothing_rad_s: float) -> float:
    """The f_c (N·m) that best explains the residuals as f_c tanh(θ̇_DT / v) (least squares)."""
    shape = np.concatenate([np.tanh(run.twin_angular_velocity_rad_s / smoothing_rad_s).ravel()
                            for run in runs])
    residual = np.concatenate([run.residual_nm.ravel() for run in runs])
    return max(float(shape @ residual / (shape @ shape)), 0.0)


def gumbel_threshold(maxima: np.ndarray, block_s: float, false_alarms_per_hour: float) -> float:
    """The level a block maximum exceeds with probability rate · W (Gumbel fit)."""
    if maxima.size < 2:
        raise ValueError('need at least two failure-free runs')
    scale = float(np.std(maxima, ddof=1)) * np.sqrt(6.0) / np.pi
    location = float(np.mean(maxima)) - EULER_GAMMA * scale
    if false_alarms_per_hour <= 0.0:
        raise ValueError(f'the false-alarm rate must be positive, got {false_alarms_per_hour}')
    # a rate above one per block cannot be asked of a block maximum: at most almost surely
    exceedance = min(false_alarms_per_hour * block_s / 3600.0, 1.0 - 1e-12)
    level = location - scale * np.log(-np.log1p(-exceedance))
    return float(max(level, np.max(maxima)))


def collapse_reference_level(seen: list[float | None], block_s: float, false_alarms_per_hour: float) -> float | None:
    """The reference tension (N) a run's motors read free at with probability rate · W: a
    run either never reads a loaded motor as free (None) or does at a largest reference
    tension that follows a Gumbel law fitted to the runs that did, and which they bound
    from below (one such run: its value). None where no run did."""
    found = np.array([value for value in seen if value is not None], dtype=float)
    if found.size == 0:
        return None
    if found.size < 2:
        return float(found[0])
    # given that a run reads a motor free, it may exceed the level this much more often
    return gumbel_threshold(found, block_s, false_alarms_per_hour * len(seen) / found.size)


def cusum_trace(normalised: np.ndarray, drift: float) -> np.ndarray:
    """max over motors of g_k = max(0, g_{k−1} + z_k − ν), per tick (z: ticks × motors)."""
    g = np.zeros(normalised.shape[1])
    trace = np.empty(normalised.shape[0])
    for k, z in enumerate(normalised):
        g = np.maximum(0.0, g + z - drift)
        trace[k] = g.max()
    return trace


@dataclass
class Calibration:
    coulomb_friction_nm: float
    epsilon_nm: float
    cusum_sigma_nm: list[float]
    cusum_drift: float
    cusum_threshold: float
    cusum_limit: float
    cusum_epsilon_nm: float
    hours: float
    runs: int
    largest_residual_nm: float
    largest_cusum: float


def calibrate(runs: list[FailureFreeRun], period_s: float, smoothing_rad_s: float,
              cusum_drift: float, false_alarms_per_hour: float, twin_friction_nm: float = 0.0) -> Calibration:
    """Thresholds for the threshold and CUSUM detectors from failure-free runs.

    CUSUM: σ_i is the spread of the friction-compensated residual; with the drift ν
    given, its three tests (the sum's level h, the limit on z, ε on |r|) each get a third
    of the budget. The sum never alarms on a single sample the limit lets pass: h is at
    least limit − ν (a smooth robot's calibration may never see z above ν, and give no
    sum to fit). Where the limit lies below ν, a sample that grows the sum has already
    alarmed on the limit: h then only needs to be positive, and is the limit itself.
    """
    coulomb = fit_coulomb_friction(runs, smoothing_rad_s)
    friction = FrictionModel(coulomb, smoothing_rad_s)
    # the motors' friction: what the residual shows beyond what the twin models itself
    coulomb += twin_friction_nm
    compensated = [run.residual_nm - friction.torque_nm(run.twin_angular_velocity_rad_s) for run in runs]
    sigma = np.std(np.vstack(compensated), axis=0)
    ticks = sum(run.residual_nm.shape[0] for run in runs)
    block_s = ticks * period_s / len(runs)
    raw_maxima = np.array([np.max(np.abs(run.residual_nm)) for run in runs])
    normalised = [np.abs(e) / sigma for e in compensated]
    cusum_maxima = np.array([np.max(cusum_trace(z, cusum_drift)) for z in normalised])
    third = false_alarms_per_hour / 3.0
    limit = gumbel_threshold(np.array([np.max(z) for z in normalised]), block_s, third)
    return Calibration(
        coulomb_friction_nm=coulomb,
        epsilon_nm=gumbel_threshold(raw_maxima, block_s, false_alarms_per_hour),
        cusum_sigma_nm=[float(s) for s in sigma],
        cusum_drift=cusum_drift,
        cusum_threshold=max(gumbel_threshold(cusum_maxima, block_s, third),
                            limit - cusum_drift if limit > cusum_drift else limit),
        cusum_limit=limit,
        cusum_epsilon_nm=gumbel_threshold(raw_maxima, block_s, third),
        hours=ticks * period_s / 3600.0,
        runs=len(runs),
        largest_residual_nm=float(raw_maxima.max()),
        largest_cusum=float(cusum_maxima.max()),
    )
