"""A package in rooms: its top holds only its base modules and its rooms; each room is small
and its docstring names the rooms it may import; those names form no circle, and no import
(function-level ones too) goes anywhere else; the base imports no room. And no module
outside a body's own room asks which body a robot has."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from conftest import REPO
from test_imports import circles, imports, module_files

# Each package in rooms, and the modules its top holds besides them (its base).
PACKAGES = {
    'cdpr_bringup': {'cli', 'paths'},
    'cdpr_control': {'config', 'kernels'},
    'cdpr_twin': set(),
    # the interface contract is the base, the node runtime its one room
    'cdpr_msgs_py': {'cdr', 'contract', 'conversions', 'dds', 'health', 'qos', 'scheduling', 'sole_writer',
                     'stamps'},
    'cdpr_fdi': set(),
}
# Rooms a package must have, as a check that the rooms are read at all.
EXPECTED = {
    'cdpr_bringup': {'runs', 'bags', 'reports', 'graph', 'scenario', 'campaigns', 'bench', 'family'},
    'cdpr_control': {'model', 'point_mass', 'platform', 'geometry', 'control', 'setup'},
    'cdpr_twin': {'models', 'nodes'},
    'cdpr_msgs_py': {'runtime'},
    'cdpr_fdi': {'detection', 'detectors', 'recovery_planning', 'recovery_strategies', 'settings', 'supervision',
                 'view', 'nodes'},
}
MOST_MODULES = 11
ALLOWED = re.compile(r'^Rooms it may import: (.+?)[.(]', re.M)
# The rooms where a body is defined: only there may code tell one body from another.
BODY_ROOMS = ('src/cdpr_control/cdpr_control/point_mass/', 'src/cdpr_control/cdpr_control/platform/')
# Ways of asking which body a robot has.
BODY_SWITCHES = re.compile(r'platform is (not )?None|is (not )?NO_TURN|isinstance\([^)]*\b(Platform\w*|PointMass|NoTurn)\b')


def root(package: str) -> Path:
    return REPO / 'src' / package / package


def rooms(package: str) -> dict[str, Path]:
    return {path.parent.name: path for path in sorted(root(package).glob('*/__init__.py'))}


def allowed(init: Path) -> set[str]:
    """The rooms a room's docstring says it may import ('none' for none)."""
    found = ALLOWED.search(ast.get_docstring(ast.parse(init.read_text())) or '')
    assert found, f'{init}: its docstring does not say "Rooms it may import: …"'
    names = {name.strip() for name in found.group(1).split(',')}
    return set() if names == {'none'} else names


def room_of(package: str, module: str) -> str | None:
    """The room of a dotted module of `package`, '' for the base, None outside the package."""
    parts = module.split('.')
    if parts[0] != package:
        return None
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] not in PACKAGES[package]) else ''


def house(package: str) -> dict[str, set[str]]:
    return {room: allowed(init) for room, init in rooms(package).items()}


def crossings(package: str, files: dict[str, Path]) -> list[tuple[str, str, str, str]]:
    """(module, room, imported module, its room) for every import that leaves a room."""
    found = []
    for name, path in files.items():
        room = room_of(package, name)
        if room is None:
            continue
        for target in imports(name, path, set(files)):
            to = room_of(package, target)
            if to not in (None, room, '') and to != package:
                found.append((name, room, target, to))
    return found


def against_the_rooms(package: str, files: dict[str, Path]) -> list[str]:
    plan = house(package)
    return [f'{module} ({room}) imports {target} ({to})' for module, room, target, to in crossings(package, files)
            if to not in plan[room]]


@pytest.mark.parametrize('package', sorted(PACKAGES))
def test_the_top_holds_only_the_base_and_the_rooms(package):
    top = {path.stem for path in root(package).glob('*.py')} - {'__init__'}
    assert top == PACKAGES[package]
    assert set(rooms(package)) >= EXPECTED[package]
    # a folder of modules without __init__.py would not be installed (find_packages)
    assert {path.parent.name for path in root(package).glob('*/*.py')} == set(rooms(package))


@pytest.mark.parametrize('package,room', [(package, room) for package in sorted(PACKAGES)
                                          for room in sorted(rooms(package))])
def test_a_room_is_small_and_names_only_rooms_that_exist(package, room):
    modules = [path for path in (root(package) / room).glob('*.py') if path.name != '__init__.py']
    assert 0 < len(modules) <= MOST_MODULES
    assert allowed(rooms(package)[room]) <= set(rooms(package)) - {room}


@pytest.mark.parametrize('package', sorted(PACKAGES))
def test_the_rooms_form_no_circle(package):
    assert circles(house(package)) == []


@pytest.mark.parametrize('package', sorted(PACKAGES))
def test_the_base_imports_no_room(package):
    files = module_files()
    for base in PACKAGES[package]:
        name = f'{package}.{base}'
        assert {room_of(package, target) for target in imports(name, files[name], set(files))} <= {None, ''}


@pytest.mark.parametrize('package', sorted(PACKAGES))
def test_every_import_between_rooms_goes_the_way_the_rooms_allow(package):
    files = module_files()
    assert crossings(package, files) or len(rooms(package)) == 1, 'the imports are read'
    assert against_the_rooms(package, files) == []


def test_an_import_against_the_rooms_is_found(tmp_path):
    """A runs module that imported the graph inside a function would be named."""
    stray = tmp_path / 'stray.py'
    stray.write_text('def start():\n    from ..graph.launcher import Graph\n    return Graph\n')
    files = {**module_files(), 'cdpr_bringup.runs.stray': stray}
    assert against_the_rooms('cdpr_bringup', files) == [
        'cdpr_bringup.runs.stray (runs) imports cdpr_bringup.graph.launcher (graph)']


def body_switches(sources: dict[str, str]) -> list[str]:
    """file:line of each line that asks which body a robot has, outside the body rooms;
    `sources`: each file's text by its path in the repository."""
    found = []
    for relative, text in sources.items():
        if relative.startswith(BODY_ROOMS):
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if BODY_SWITCHES.search(line.split('#')[0]):
                found.append(f'{relative}:{number}: {line.strip()}')
    return found


def test_no_module_outside_a_body_room_asks_which_body_it_has():
    sources = {path.relative_to(REPO).as_posix(): path.read_text()
               for path in sorted((REPO / 'src').glob('cdpr_*/cdpr_*/**/*.py'))}
    assert any(name.startswith(BODY_ROOMS) for name in sources), 'the body rooms are read'
    assert body_switches(sources) == []


@pytest.mark.parametrize('line', ['    if robot.platform is None:', 'x = a if robot.platform is not None else b',
                                  '        if isinstance(self.recovery, PlatformRecovery):',
                                  '    if isinstance(motion.turn, NoTurn):', '    if motion.turn is not NO_TURN:'])
def test_a_body_switch_is_found(line):
    stray = 'src/cdpr_fdi/cdpr_fdi/stray.py'
    assert body_switches({stray: f'"""A module."""\n{line}\n'}) == [f'{stray}:2: {line.strip()}']
    assert body_switches({BODY_ROOMS[1] + 'stray.py': line}) == []
