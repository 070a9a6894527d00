"""Failure detectors behind one interface, chosen by name (parameter `detector`).

Rooms it may import: none.
"""
from __future__ import annotations

from .base import Detector
from .cusum import CusumDetector
from .threshold import ThresholdDetector

DETECTORS = ('threshold', 'cusum')


def make_detector(config) -> Detector:
    """The detector an `FdiConfig` names, with its thresholds."""
    if config.detector == 'threshold':
        return ThresholdDetector(config.epsilon_nm)
    if config.detector == 'cusum':
        return CusumDetector(config.cusum_sigma_nm, config.cusum_drift, config.cusum_threshold,
                             config.cusum_limit, config.cusum_epsilon_nm, config.residual_friction)
    raise ValueError(f'unknown detector {config.detector!r}; one of {", ".join(DETECTORS)}')


__all__ = ['DETECTORS', 'Detector', 'CusumDetector', 'ThresholdDetector', 'make_detector']
