"""No circle in the imports between the project's modules: each module can be read, and
tested, knowing only those below it (function-level imports count too)."""
from __future__ import annotations

import ast
from pathlib import Path

from conftest import REPO

SOURCES = REPO / 'src'


def module_files() -> dict[str, Path]:
    """Dotted module name → file, for every module of the five packages."""
    files = {}
    for path in SOURCES.glob('cdpr_*/cdpr_*/**/*.py'):
        parts = path.relative_to(SOURCES).with_suffix('').parts[1:]   # below src/<package>/
        name = '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)
        files[name] = path
    return files


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The project modules `name` imports anywhere in its file."""
    package = name if path.name == '__init__.py' else name.rsplit('.', 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package.split('.')[:len(package.split('.')) - node.level + 1] if node.level else []
            target = '.'.join(base + ([node.module] if node.module else []))
            candidates = [target, *(f'{target}.{alias.name}' for alias in node.names)]
        elif isinstance(node, ast.Import):
            candidates = [alias.name for alias in node.names]
        else:
            continue
        found |= {candidate for candidate in candidates if candidate in known and candidate != name}
    return found


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan)."""
    index, low, stack, on_stack, groups = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for after in graph[node]:
            if after not in index:
                visit(after)
                low[node] = min(low[node], low[after])
            elif after in on_stack:
                low[node] = min(low[node], index[after])
        if low[node] == index[node]:
            group = []
            while not group or group[-1] != node:
                group.append(stack.pop())
                on_stack.discard(group[-1])
            if len(group) > 1:
                groups.append(sorted(group))

    for node in graph:
        if node not in index:
            visit(node)
    return groups


def test_no_two_modules_import_each_other_even_through_others():
    files = module_files()
    graph = {name: imports(name, path, set(files)) for name, path in files.items()}
    assert 'cdpr_bringup.campaigns.campaign_run' in graph['cdpr_bringup.campaigns.dask_cluster'], 'the graph is read'
    assert circles(graph) == []


def test_a_circle_is_found():
    assert circles({'a': {'b'}, 'b': {'c'}, 'c': {'a'}, 'd': {'a'}}) == [['a', 'b', 'c']]


def test_the_contract_imports_nothing_of_the_node_runtime():
    files = module_files()
    contract_side = {name: path for name, path in files.items()
                     if name.startswith('cdpr_msgs_py') and not name.startswith('cdpr_msgs_py.runtime')}
    runtime = {name for name in files if name.startswith('cdpr_msgs_py.runtime')}
    assert 'cdpr_msgs_py.contract' in contract_side and 'cdpr_msgs_py.runtime.node' in runtime
    assert {name: imports(name, path, set(files)) & runtime for name, path in contract_side.items()
            if imports(name, path, set(files)) & runtime} == {}
