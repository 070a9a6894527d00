"""cdpr-bench fdi: detection, identification, false alarms and recovery of each detector.

A campaign on a plant (`--fidelity`; the elastic plant by default, the field plant the
stand-in for the paper's rig), with plant seeds other than those the calibration was
measured on: every cable breaking at the paper's point of every motion, both directions,
once per detector; and every motion failure-free for at least ten minutes per detector.
The detectors: ours, `threshold` and `cusum` at the thresholds calibrated for the plant,
and `paper_threshold`, the paper's detector as it ran on its robot (threshold, ε = 0.3 N·m,
§5.1), in a campaign of its own (DIR/paper_threshold).
"""
from __future__ import annotations

from pathlib import Path

from cdpr_control.geometry.motions import motion_names

from ..campaigns.campaign import build_matrix, run_campaign, summarize, summary_markdown, write_summary_csv
from ..paths import DEFAULT_MOTIONS, config_file

DETECTORS = ('threshold', 'cusum')
PAPER_DETECTOR = 'paper_threshold'
PAPER_EPSILON_NM = 0.3
FAILURE_SEEDS = (10,)
FAILURE_FREE_SEEDS = (10, 11, 12, 13, 14)
TARGETS = {'along_delay_median_ms': '≤ 30 (paper 30–80)',
           'orthogonal_delay_median_ms': '≤ 100 (paper 200–290)',
           'identification_pct': '100', 'false_alarms_per_hour': '0 over ≥ 10 min',
           'recovery_success_pct': '100'}
FIGURES = ('along_delay_median_ms', 'along_delay_max_ms', 'orthogonal_delay_median_ms',
           'orthogonal_delay_max_ms', 'identification_pct', 'false_alarms_per_hour',
           'failure_free_hours', 'recovery_success_pct', 'min_tension_n', 'final_error_max_m',
           'errors')


def bench_fdi(config: str, out_dir: str | Path, jobs: int | None = None,
              fidelity: str = 'elastic') -> dict:
    """{detector: figures}, with the hours of failure-free motion behind the false-alarm rate."""
    motions = motion_names(config_file(DEFAULT_MOTIONS))
    figures = {}
    for label, detectors, epsilon_nm in ((None, DETECTORS, None),
                                         (PAPER_DETECTOR, ('threshold',), PAPER_EPSILON_NM)):
        settings = dict(config=config, motions_file=DEFAULT_MOTIONS, engine='inprocess',
                        epsilon_nm=epsilon_nm)
        runs = build_matrix(motions, [1, 2, 3, 4], fidelities=[fidelity], detectors=detectors,
                            seeds=FAILURE_SEEDS, failure_free=False, **settings)
        runs += build_matrix(motions, [], fidelities=[fidelity], detectors=detectors,
                             seeds=FAILURE_FREE_SEEDS, failure_free=True, **settings)
        out = Path(out_dir) / label if label else Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        rows = run_campaign(runs, out, jobs)
        write_summary_csv(rows, out / 'summary.csv')
        (out / 'summary.md').write_text(summary_markdown(rows))
        summary = summarize(rows)
        for detector in detectors:
            group = summary[f'{detector}/{fidelity}']
            figures[label or detector] = {key: group[key] for key in FIGURES}
    return figures


def table(figures: dict) -> list[str]:
    lines = [f'  {"figure":<30} ' + ' '.join(f'{d:>15}' for d in figures) + '   target']
    for key in FIGURES:
        cells = ' '.join(f'{fmt(figures[d][key]):>15}' for d in figures)
        lines.append(f'  {key:<30} {cells}   {TARGETS.get(key, "")}')
    return lines


def fmt(value) -> str:
    return '–' if value is None else f'{value:.3g}' if isinstance(value, float) else str(value)
