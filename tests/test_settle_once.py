"""A run is settled in one pass: each file is read once, and no value read from the
robot, the motion or the plant is read through the Section helper again."""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control import config

# Read twice by design: the fdi section is replaced by the calibrated one and read as
# such; the control section and its period are read by the gains and by the run; a
# set-up's robot is read from its robot file, then from the set-up that holds it.
READ_AGAIN_BY_DESIGN = {'fdi', 'control', 'control.period_s', 'robot'}


def reads_of_settling(monkeypatch, options: ScenarioOptions) -> tuple[Counter, Counter]:
    """(YAML files read, dotted keys read through Section.raw) while `options` are settled."""
    files, keys = Counter(), Counter()
    read_text, raw = Path.read_text, config.Section.raw

    def counted_read_text(path, *args, **kwargs):
        if path.suffix == '.yaml':
            files[path.name] += 1
        return read_text(path, *args, **kwargs)

    def counted_raw(section, name, default=...):
        keys[section.key(name)] += 1
        return raw(section, name, default)

    config.paper_defaults()   # the defaults are read once per process, not per run
    monkeypatch.setattr(Path, 'read_text', counted_read_text)
    monkeypatch.setattr(config.Section, 'raw', counted_raw)
    build_scenario(options)
    monkeypatch.undo()
    return files, keys


@pytest.mark.parametrize('robot, fidelity', [('paper_robot.yaml', 'elastic'), ('paper_rig', 'field'),
                                             ('eight_cable_robot.yaml', 'rigid')])
def test_settling_a_run_reads_each_file_once_and_each_value_once(monkeypatch, robot, fidelity):
    files, keys = reads_of_settling(monkeypatch, ScenarioOptions(
        config=robot, motion='along-1', fidelity=fidelity, fail_cables=[2]))
    assert files and keys['robot.motor.inertia_kg_m2'] == 1, 'the reads are counted'
    assert {name: count for name, count in files.items() if count > 1} == {}
    assert {key for key, count in keys.items() if count > 1} <= READ_AGAIN_BY_DESIGN
