"""Each package.xml declares what its package imports, and nothing it does not: rosdep
installs what is declared, and a package that imports more breaks in a workspace where
only its declared dependencies are installed. The tests `colcon test` runs for a package
(its setup.cfg) count too, against its exec and test dependencies."""
from __future__ import annotations

import ast
import configparser
import sys
import xml.etree.ElementTree as ElementTree
from collections import Counter
from pathlib import Path

import pytest
from ament_index_python import get_packages_with_prefixes

from cdpr_msgs_py import contract

from conftest import REPO

SOURCES = REPO / 'src'
PACKAGES = sorted(path.parent.name for path in SOURCES.glob('*/package.xml'))
TESTS = REPO / 'tests'

# Python modules that are not ROS packages: their rosdep keys.
ROSDEP_KEYS = {'numpy': 'python3-numpy', 'yaml': 'python3-yaml', 'matplotlib': 'python3-matplotlib',
               'scipy': 'python3-scipy', 'pytest': 'python3-pytest', 'rosbags': 'python3-rosbags-pip',
               'numba': 'python3-numba'}
# Modules with no rosdep key: installed with pip, as docs/environment.md's workspace section says.
PIP_ONLY = {'mcap': 'mcap', 'distributed': 'distributed'}


def imported_modules(path: Path, module_level_only: bool = False) -> set[str]:
    """The top-level names `path` imports (absolute imports, inside functions too)."""
    tree = ast.parse(path.read_text(), str(path))
    nodes = tree.body if module_level_only else ast.walk(tree)
    names = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            names.update(alias.name.split('.')[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            names.add(node.module.split('.')[0])
    return names - set(sys.stdlib_module_names)


def key(module: str) -> str | None:
    """The package.xml key of an imported module; None for a pip-only one."""
    if module in ROSDEP_KEYS:
        return ROSDEP_KEYS[module]
    if module in PIP_ONLY:
        return None
    assert module in PACKAGES or module in get_packages_with_prefixes(), (
        f'{module} is neither a ROS package nor in ROSDEP_KEYS / PIP_ONLY')
    return module


def declared(package: str, *kinds: str) -> list[str]:
    root = ElementTree.parse(SOURCES / package / 'package.xml').getroot()
    return [element.text for kind in kinds for element in root.iter(kind)]


def colcon_tests(package: str) -> list[Path]:
    """The test files pytest runs for `package` in its folder (setup.cfg's testpaths)."""
    config = configparser.ConfigParser()
    config.read(SOURCES / package / 'setup.cfg')
    return [(SOURCES / package / entry).resolve()
            for entry in config['tool:pytest']['testpaths'].split()]


def needed(package: str) -> set[str]:
    """The keys the code of `package` needs: what it imports, and the message packages of
    the topics cdpr_msgs_py.contract names (it imports them by name: message_class)."""
    modules = {module for path in (SOURCES / package / package).rglob('*.py')
               for module in imported_modules(path)} - {package}
    keys = {key(module) for module in modules} - {None}
    if package == 'cdpr_msgs_py':
        keys |= {topic.type.split('/')[0] for topic in contract.TOPICS.values()}
    return keys


@pytest.mark.parametrize('package', PACKAGES)
def test_exec_depends_are_what_the_package_imports(package):
    declarations = declared(package, 'exec_depend', 'depend')
    assert len(declarations) == len(set(declarations)), declarations
    assert set(declarations) == needed(package)


@pytest.mark.parametrize('package', PACKAGES)
def test_its_colcon_tests_need_only_what_it_declares(package):
    modules = {module for path in colcon_tests(package) for module in imported_modules(path)}
    # every test file in tests/ runs under its conftest
    modules |= imported_modules(TESTS / 'conftest.py', module_level_only=True)
    local = {path.stem for path in TESTS.glob('*.py')}
    keys = {key(module) for module in modules - local} - {None, package}
    available = set(declared(package, 'exec_depend', 'depend', 'test_depend'))
    assert keys <= available, f'not in {package}/package.xml: {sorted(keys - available)}'
    assert 'python3-pytest' in declared(package, 'test_depend')


def test_each_test_file_runs_under_one_package_at_most():
    files = Counter(path for package in PACKAGES for path in colcon_tests(package))
    # every package the tests import is found; a file checked per package at least
    tested = {module for path in TESTS.glob('test_*.py') for module in imported_modules(path)}
    assert {module for module in tested if module.startswith('cdpr_')} <= set(PACKAGES)
    assert len(files) >= len(PACKAGES)
    assert all(path.is_file() for path in files), [str(p) for p in files if not p.is_file()]
    assert {path: count for path, count in files.items() if count > 1} == {}


def test_the_pip_only_modules_are_on_the_workspace_pages_pip_line():
    pip_lines = [line for line in (REPO / 'docs' / 'environment.md').read_text().splitlines()
                 if line.startswith('pip install')]
    for module, distribution in PIP_ONLY.items():
        assert any(distribution in line.split() for line in pip_lines), module
