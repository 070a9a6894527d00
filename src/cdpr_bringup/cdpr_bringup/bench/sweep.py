"""cdpr-bench sweep: how each detector, calibrated on the nominal plant, fares on plants
that differ from it.

One axis at a time, the plant is changed from the set-up's (`--config`) by a factor on
the settled value of its keys: the end-effector's true mass ±10 %, the motors' viscous
and Coulomb friction ×0.5–2, the cables' axial stiffness ×0.3–3, and on the field plant
the drive's command delay ×0–4 (0–2 control periods). Each cell is a set-up file in OUT/cells/ (the set-up's
own, with the change), so the controller, the twin and the detectors' calibration stay
those of the nominal robot: only the plant differs, as a real robot differs from its
model. In each cell every motion breaks cable 4 at the paper's instant and runs
failure-free (forward, one seed each), judged by every detector as in cdpr-bench roc at
its calibrated thresholds: identification %, false alarms per hour and the median delay
per motion family.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from cdpr_control.config import load_config, load_yaml, with_defaults
from cdpr_control.setup.settings import unflatten
from cdpr_fdi.detectors import DETECTORS

from .fdi import fmt
from .roc import FAMILIES, judged_runs, roc_points, roc_runs, write_rows
from ..paths import config_file

NOMINAL = 1.0
SEEDS = (20,)


@dataclass(frozen=True)
class Axis:
    """Plant keys (dotted, per fidelity: the field plant has its own line) scaled together
    by each of `factors`; an axis a fidelity has no keys for is left out."""

    name: str
    keys: dict[str, tuple[str, ...]]
    factors: tuple[float, ...]


MISMATCH = 'plant.elastic.mismatch'
AXES = (
    Axis('end-effector mass', {fidelity: (f'{MISMATCH}.mass',) for fidelity in ('elastic', 'field')},
         (0.9, 1.1)),
    Axis('motor friction', {fidelity: (f'{MISMATCH}.viscous_friction', f'{MISMATCH}.static_friction')
                            for fidelity in ('elastic', 'field')}, (0.5, 2.0)),
    Axis('cable stiffness', {fidelity: (f'plant.{fidelity}.cable_axial_stiffness_n',)
                             for fidelity in ('elastic', 'field')}, (0.3, 3.0)),
    # the field drive's 1 ms: none, and one or two control periods
    Axis('drive delay', {'field': ('plant.field.command_delay_s',)}, (0.0, 2.0, 4.0)),
)
FIGURES = ('identification_pct', 'false_alarms_per_hour') + tuple(
    f'{family}_delay_median_ms' for family in FAMILIES)


def settled_value(document: dict, key: str):
    value = document
    for part in key.split('.'):
        value = value[part]
    return value


def scaled(value, factor: float):
    """A plant value times `factor`: a list of one per motor, motor by motor."""
    return [entry * factor for entry in value] if isinstance(value, list) else value * factor


def cell_setup(config: Path, changes: dict[str, float]) -> dict:
    """The set-up at `config` (a robot file or a set-up) with `changes` (dotted key → value),
    its robot file named by absolute path, so the cell can live in another folder."""
    document = load_yaml(config)
    if 'robot_file' in document:
        document['robot_file'] = str((config.parent / document['robot_file']).resolve())
    # the changes, and the set-up's every other key
    changed, _ = with_defaults(unflatten(changes), document)
    return changed


def cells(config: Path, out: Path, fidelity: str) -> dict[str, Path]:
    """Cell label → its set-up file: the nominal plant, then each axis's factors."""
    settled = load_config(config).data
    folder = out / 'cells'
    folder.mkdir(parents=True, exist_ok=True)
    made = {}
    for label, changes in [('nominal', {})] + [
            (f'{axis.name} ×{factor:g}', {key: scaled(settled_value(settled, key), factor)
                                          for key in axis.keys[fidelity]})
            for axis in AXES if fidelity in axis.keys for factor in axis.factors]:
        path = folder / f'{len(made):02d}.yaml'
        path.write_text(f'# cdpr-bench sweep cell: {label}\n'
                        + yaml.safe_dump(cell_setup(config, changes), sort_keys=False))
        made[label] = path
    return made


def bench_sweep(config: str, out_dir: str | Path, fidelity: str = 'elastic',
                jobs: int | None = None) -> dict:
    """{cell: {detector: figures}}; writes sweep.csv and sweep.png into `out_dir`."""
    out = Path(out_dir)
    made = cells(config_file(config), out, fidelity)
    runs = [run for path in made.values()
            for run in roc_runs(str(path), fidelity, SEEDS, SEEDS, directions=(False,),
                                factors=(NOMINAL,))]
    rows = judged_runs(runs, jobs)
    label_of = {str(path): label for label, path in made.items()}
    for row in rows:
        row['cell'] = label_of[row['config']]
    write_rows(rows, out / 'sweep.csv')
    figures = {label: {detector: curve[0] for detector, curve in roc_points(
                   [row for row in rows if row['cell'] == label], (NOMINAL,)).items()}
               for label in made}
    plot_sweep(figures, out / 'sweep.png', fidelity)
    return figures


def plot_sweep(figures: dict, path: Path, fidelity: str) -> None:
    """A heat map: a row per cell, a column per detector × figure, each column coloured on
    its own scale (red: worse)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    labels = list(figures)
    columns = [(detector, key) for detector in DETECTORS for key in FIGURES]
    values = np.array([[np.nan if figures[label][d][k] is None else figures[label][d][k]
                        for d, k in columns] for label in labels], dtype=float)
    badness = np.full_like(values, np.nan)
    for j, (_, key) in enumerate(columns):
        column = values[:, j]
        # identification: less is worse; false alarms and delays: more is worse
        worse = 100.0 - column if key == 'identification_pct' else column
        span = np.nanmax(worse) - np.nanmin(worse) if np.isfinite(worse).any() else 0.0
        badness[:, j] = (worse - np.nanmin(worse)) / span if span > 0 else 0.0
    figure, axis = plt.subplots(figsize=(1.3 * len(columns) + 3, 0.5 * len(labels) + 2))
    axis.imshow(badness, cmap='RdYlGn_r', vmin=0.0, vmax=1.0, aspect='auto')
    for i in range(len(labels)):
        for j in range(len(columns)):
            text = '–' if np.isnan(values[i, j]) else f'{values[i, j]:.3g}'
            axis.text(j, i, text, ha='center', va='center', fontsize=8)
    axis.set_yticks(range(len(labels)), labels)
    axis.set_xticks(range(len(columns)), [f'{d}\n{k.replace("_median_ms", " ms").replace("_", " ")}'
                                          for d, k in columns], fontsize=7)
    axis.set_title(f'Detectors calibrated on the nominal {fidelity} plant, on plants that differ')
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def table(figures: dict) -> list[str]:
    header = f'  {"cell":<26} {"detector":<10} ' + ' '.join(
        f'{key.replace("_median_ms", " ms"):>22}' for key in FIGURES)
    lines = [header]
    for label, by_detector in figures.items():
        for detector, point in by_detector.items():
            lines.append(f'  {label:<26} {detector:<10} ' + ' '.join(
                f'{fmt(point[key]):>22}' for key in FIGURES))
    return lines

