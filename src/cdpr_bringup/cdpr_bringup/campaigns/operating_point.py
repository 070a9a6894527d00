"""A detector's operating point from its false-alarm rate: the exact Poisson bound on a
rate counted over simulated hours, each sensitivity's figures from the judged runs of
`cdpr-bench far` (far.csv), and the choice `cdpr-calibrate --from-far` makes from them."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

CONFIDENCE = 0.95


def poisson_upper_bound(count: int, confidence: float = CONFIDENCE) -> float:
    """The exact one-sided upper bound on a Poisson mean from `count` events: the μ with
    P(X ≤ count; μ) = 1 − confidence (= χ²_{confidence}(2 count + 2) / 2), by bisection on
    the Poisson distribution function, which falls as μ grows."""
    def cdf(mean: float) -> float:
        terms = np.arange(count + 1)
        logs = terms * math.log(mean) - mean - np.array([math.lgamma(i + 1.0) for i in terms])
        return float(np.exp(logs).sum())

    low, high = float(count), count + 10.0 * math.sqrt(count + 1.0) + 10.0
    for _ in range(100):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if cdf(middle) > 1.0 - confidence else (low, middle)
    return 0.5 * (low + high)


def rate_upper_per_hour(false_alarms: int, hours: float, confidence: float = CONFIDENCE) -> float:
    """The 95 % upper bound on false alarms per hour from `false_alarms` in `hours`."""
    return poisson_upper_bound(false_alarms, confidence) / hours


def percentile(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def far_points(rows: list[dict]) -> dict:
    """{(plant, detector): [figures per sensitivity, factor ascending]} from the rows."""
    points = {}
    for plant, detector in sorted({(r['fidelity'], r['detector']) for r in rows}):
        curve = points[(plant, detector)] = []
        for factor in sorted({r['factor'] for r in rows if (r['fidelity'], r['detector']) == (plant, detector)}):
            group = [r for r in rows if (r['fidelity'], r['detector'], r['factor']) == (plant, detector, factor)]
            free = [r for r in group if r['cable'] is None]
            failures = [r for r in group if r['cable'] is not None]
            hours = sum(r['hours'] for r in free)
            alarms = sum(r['false_alarm_episodes'] for r in free)
            delays = [r['delay_ms'] for r in failures if r['delay_ms'] is not None]
            upper = rate_upper_per_hour(alarms, hours) if hours else None
            curve.append(dict(
                # the detector's own ε (and h): what the factor scaled
                factor=factor, epsilon_nm=group[0]['cusum_epsilon_nm' if detector == 'cusum' else 'epsilon_nm'],
                cusum_h=group[0]['cusum_threshold'] if detector == 'cusum' else None,
                failure_free_hours=hours, false_alarms=alarms,
                false_alarms_per_hour=alarms / hours if hours else None,
                upper_per_hour=upper,
                arl0_h=hours / alarms if alarms else None,
                arl0_lower_h=1.0 / upper if upper else None,
                naming_episodes=sum(r['naming_episodes'] for r in free),
                pushes_applied=sum(r['pushes_applied'] for r in free),
                pushes_named=sum(r['pushes_named'] for r in free),
                failure_runs=len(failures),
                delay_median_ms=percentile(delays, 50), delay_p95_ms=percentile(delays, 95),
                delay_max_ms=max(delays) if delays else None,
                missed=sum(r['delay_ms'] is None and not r['false_alarms'] for r in failures),
                early=sum(bool(r['false_alarms']) for r in failures),
                identification_pct=(100.0 * sum(bool(r['identified']) for r in failures) / len(failures)
                                    if failures else None)))
    return points


def choose(curve: list[dict], target_per_hour: float) -> dict | None:
    """The operating point for a target rate: the most sensitive swept point whose 95 %
    upper bound is below the target, as is every less sensitive one (a point that meets it
    between two that do not is luck of the draw, not an operating point); None: none does."""
    chosen = None
    for point in reversed(curve):   # from the least sensitive
        if point['upper_per_hour'] is None or point['upper_per_hour'] >= target_per_hour:
            break
        chosen = point
    return chosen


def read_rows(path: str | Path) -> list[dict]:
    """far.csv's rows, with numbers, booleans and empty cells (None) as written."""
    def value(text: str):
        if text == '':
            return None
        if text in ('True', 'False'):
            return text == 'True'
        try:
            number = float(text)
        except ValueError:
            return text
        return int(number) if number.is_integer() and '.' not in text and 'e' not in text else number

    with open(path, newline='') as file:
        return [{key: value(text) for key, text in row.items()} for row in csv.DictReader(file)]


