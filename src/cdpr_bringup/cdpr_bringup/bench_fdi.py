"""cdpr-bench fdi: detection, identification, false alarms and recovery of each detector.

A campaign on the elastic plant (the stand-in for the real robot, whose failure-free
K_t is about the paper's 0.16 N·m), with plant seeds other than those the shipped
calibration was measured on: every cable breaking at the paper's point of every motion,
both directions, once per detector; and every motion failure-free for at least ten
minutes per detector.
"""
from __future__ import annotations

from pathlib import Path

from cdpr_control.motions import motion_names

from .campaign import build_matrix, run_campaign, summarize, summary_markdown, write_summary_csv
from .paths import DEFAULT_MOTIONS, config_file

DETECTORS = ('threshold', 'cusum')
FAILURE_SEEDS = (10,)
FAILURE_FREE_SEEDS = (10, 11, 12, 13, 14)
TARGETS = {'along_delay_median_ms': '≤ 30 (paper 30–80)',
           'orthogonal_delay_median_ms': '≤ 100 (paper 200–290)',
           'identification_pct': '100', 'false_alarms_per_hour': '0 over ≥ 10 min',
           'recovery_success_pct': '100'}


def bench_fdi(config: str, out_dir: str | Path, jobs: int | None = None) -> dict:
    """{detector: figures} and the hours of failure-free motion behind the false-alarm rate."""
    motions = motion_names(config_file(DEFAULT_MOTIONS))
    settings = dict(config=config, motions_file=DEFAULT_MOTIONS, engine='inprocess', epsilon_nm=None)
    runs = build_matrix(motions, [1, 2, 3, 4], fidelities=['elastic'], detectors=DETECTORS,
                        seeds=FAILURE_SEEDS, failure_free=False, **settings)
    runs += build_matrix(motions, [], fidelities=['elastic'], detectors=DETECTORS,
                         seeds=FAILURE_FREE_SEEDS, failure_free=True, **settings)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = run_campaign(runs, out, jobs)
    write_summary_csv(rows, out / 'summary.csv')
    (out / 'summary.md').write_text(summary_markdown(rows))
    summary = summarize(rows)
    figures = {}
    for detector in DETECTORS:
        group = summary[f'{detector}/elastic']
        figures[detector] = {key: group[key] for key in (
            'along_delay_median_ms', 'along_delay_max_ms', 'orthogonal_delay_median_ms',
            'orthogonal_delay_max_ms', 'identification_pct', 'false_alarms_per_hour',
            'failure_free_hours', 'recovery_success_pct', 'min_tension_n', 'final_error_max_m',
            'errors')}
    return figures


def table(figures: dict) -> list[str]:
    lines = [f'  {"figure":<30} ' + ' '.join(f'{d:>10}' for d in DETECTORS) + '   target']
    for key in figures[DETECTORS[0]]:
        cells = ' '.join(f'{fmt(figures[d][key]):>10}' for d in DETECTORS)
        lines.append(f'  {key:<30} {cells}   {TARGETS.get(key, "")}')
    return lines


def fmt(value) -> str:
    return '–' if value is None else f'{value:.3g}' if isinstance(value, float) else str(value)
