"""cdpr_bringup's rooms import each other one way only: each room's docstring names the
rooms it may import, those names form no circle, and no import (function-level ones too)
goes anywhere else."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from conftest import REPO
from test_imports import circles, imports, module_files

PACKAGE = 'cdpr_bringup'
ROOT = REPO / 'src' / PACKAGE / PACKAGE
BASE = {'cli', 'paths'}
MOST_MODULES = 11
ALLOWED = re.compile(r'^Rooms it may import: (.+?)[.(]', re.M)


def rooms() -> dict[str, Path]:
    return {path.parent.name: path for path in sorted(ROOT.glob('*/__init__.py'))}


def allowed(init: Path) -> set[str]:
    """The rooms a room's docstring says it may import ('none' for none)."""
    found = ALLOWED.search(ast.get_docstring(ast.parse(init.read_text())) or '')
    assert found, f'{init}: its docstring does not say "Rooms it may import: …"'
    names = {name.strip() for name in found.group(1).split(',')}
    return set() if names == {'none'} else names


def room_of(module: str) -> str | None:
    """The room of a dotted cdpr_bringup module, '' for the base, None outside the package."""
    parts = module.split('.')
    if parts[0] != PACKAGE:
        return None
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] not in BASE) else ''


def house() -> dict[str, set[str]]:
    return {room: allowed(init) for room, init in rooms().items()}


def crossings(files: dict[str, Path]) -> list[tuple[str, str, str, str]]:
    """(module, room, imported module, its room) for every import that leaves a room."""
    found = []
    for name, path in files.items():
        room = room_of(name)
        if room is None:
            continue
        for target in imports(name, path, set(files)):
            to = room_of(target)
            if to not in (None, room, '') and to != PACKAGE:
                found.append((name, room, target, to))
    return found


def test_the_top_holds_only_the_base_and_the_rooms():
    top = {path.stem for path in ROOT.glob('*.py')} - {'__init__'}
    assert top == BASE
    assert set(rooms()) >= {'runs', 'bags', 'reports', 'graph', 'scenario', 'campaigns', 'bench'}
    # a folder of modules without __init__.py would not be installed (find_packages)
    assert {path.parent.name for path in ROOT.glob('*/*.py')} == set(rooms())


@pytest.mark.parametrize('room', sorted(rooms()))
def test_a_room_is_small_and_names_only_rooms_that_exist(room):
    modules = [path for path in (ROOT / room).glob('*.py') if path.name != '__init__.py']
    assert 0 < len(modules) <= MOST_MODULES
    assert allowed(rooms()[room]) <= set(rooms()) - {room}


def test_the_rooms_form_no_circle():
    assert circles(house()) == []


def test_the_base_imports_no_room():
    files = module_files()
    for base in BASE:
        name = f'{PACKAGE}.{base}'
        assert {room_of(target) for target in imports(name, files[name], set(files))} <= {None, ''}


def against_the_rooms(files: dict[str, Path]) -> list[str]:
    plan = house()
    return [f'{module} ({room}) imports {target} ({to})' for module, room, target, to in crossings(files)
            if to not in plan[room]]


def test_every_import_between_rooms_goes_the_way_the_rooms_allow():
    files = module_files()
    assert ('cdpr_bringup.scenario.command', 'scenario', 'cdpr_bringup.runs.engine', 'runs') \
        in crossings(files), 'the imports are read'
    assert against_the_rooms(files) == []


def test_an_import_against_the_rooms_is_found(tmp_path):
    """A runs module that imported the graph inside a function would be named."""
    stray = tmp_path / 'stray.py'
    stray.write_text('def start():\n    from ..graph.launcher import Graph\n    return Graph\n')
    files = {**module_files(), 'cdpr_bringup.runs.stray': stray}
    assert against_the_rooms(files) == [
        'cdpr_bringup.runs.stray (runs) imports cdpr_bringup.graph.launcher (graph)']
