"""Loading YAML configuration with errors that name the key and the file.

A robot file holds the robot alone (`robot:`); a robot's set-up names its robot file
(`robot_file:`, relative to the set-up) and holds the options it runs with that differ
from the paper's. load_config fills in every option left out from the files of
defaults/ beside this module (one per section: control, twin, plant, fdi, recovery,
scheduling, streams, health, markers), key by key, and remembers which keys it filled in
(Section.is_default). A file with both a robot and options still loads.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from cdpr_msgs_py.contract import INT64_MAX, INT64_MIN


class ConfigError(ValueError):
    """A configuration value is missing or invalid; the message names key and file."""

    def __init__(self, path: str | Path, key: str, problem: str):
        self.path = str(path)
        self.key = key
        self.problem = problem
        super().__init__(f"{self.path}: '{key}' {problem}")

    def __reduce__(self):
        # rebuilt from its parts when it crosses from a worker process: pickle's default
        # would call __init__ with the message alone, which breaks the pool
        return type(self), (self.path, self.key, self.problem)


def load_yaml(path: str | Path) -> dict:
    """Read a YAML mapping from `path`; anything else is a ConfigError."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise ConfigError(path, '<file>', f'cannot be read: {err.strerror}') from err
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ConfigError(path, '<file>', f'is not valid YAML: {err}') from err
    if not isinstance(data, dict):
        raise ConfigError(path, '<file>', 'must hold a YAML mapping at the top level')
    return data


def _is_number(value: Any) -> bool:
    """An int or a float as YAML reads them; a bool is not a number here."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_finite(value: int | float) -> bool:
    """Finite as a float: an integer beyond the float range is not (float() would raise)."""
    try:
        return bool(np.isfinite(float(value)))
    except OverflowError:
        return False


@dataclass(frozen=True)
class Bounds:
    """What a loader accepts for a key, for the ROS parameter that carries it: numbers
    from `low` to `high` (None: unbounded on that side; `low` itself refused when
    `low_excluded`), or a string among `choices`."""

    low: float | None = None
    high: float | None = None
    low_excluded: bool = False
    choices: tuple[str, ...] = ()

    def text(self) -> str:
        """The constraint in words, as `ros2 param describe` shows it."""
        if self.choices:
            return f'one of {", ".join(self.choices)}'
        sides = [f'{">" if self.low_excluded else ">="} {self.low:g}'] if self.low is not None else []
        if self.high is not None:
            sides.append(f'<= {self.high:g}')
        return ' and '.join(sides)


class Section:
    """A view on one mapping of a config file that reports dotted key paths.

    The sections taken from one another share `bounds`: dotted key → the Bounds a loader
    checked its value against, gathered as the loaders read."""

    def __init__(self, data: Mapping[str, Any], path: str | Path, prefix: str = '',
                 defaulted: frozenset[str] = frozenset(), sources: Mapping[str, str] | None = None,
                 bounds: dict[str, Bounds] | None = None):
        if not isinstance(data, Mapping):
            raise ConfigError(path, prefix or '<root>', 'must be a mapping')
        self.data = data
        self.path = str(path)
        self.prefix = prefix
        # dotted keys whose values come from defaults/, not from the file
        self.defaulted = defaulted
        # top-level sections read from another file than `path` (a set-up's robot file)
        self.sources = dict(sources or {})
        self.bounds = {} if bounds is None else bounds

    def key(self, name: str) -> str:
        return f'{self.prefix}.{name}' if self.prefix else name

    def error(self, name: str, problem: str) -> ConfigError:
        return ConfigError(self.path, self.key(name), problem)

    def has(self, name: str) -> bool:
        return name in self.data

    def is_default(self, name: str) -> bool:
        """The value of `name` is the default's: the file does not set it."""
        return self.key(name) in self.defaulted

    def raw(self, name: str, default: Any = ...) -> Any:
        if name not in self.data:
            if default is ...:
                raise self.error(name, 'is missing')
            return default
        return self.data[name]

    def section(self, name: str, default: Any = ...) -> 'Section':
        path = self.path if self.prefix else self.sources.get(name, self.path)
        return Section(self.raw(name, default), path, self.key(name), self.defaulted,
                       bounds=self.bounds)

    def number(self, name: str, default: Any = ..., *, positive: bool = False,
               non_negative: bool = False, minimum: float | None = None,
               maximum: float | None = None) -> float:
        bounds = dict(positive=positive, non_negative=non_negative, minimum=minimum, maximum=maximum)
        self._keep_bounds(name, **bounds)
        return self._checked_number(name, self.raw(name, default), **bounds)

    def _keep_bounds(self, name: str, *, positive: bool = False, non_negative: bool = False,
                    minimum: float | None = None, maximum: float | None = None) -> None:
        """Remember the bounds a number read as `name` is checked against (`bounds`)."""
        if positive or non_negative or minimum is not None or maximum is not None:
            low = minimum if minimum is not None else 0.0 if positive or non_negative else None
            self.bounds[self.key(name)] = Bounds(low, maximum, low_excluded=positive and minimum is None)

    def _checked_number(self, name: str, value: Any, *, positive: bool = False,
                       non_negative: bool = False, minimum: float | None = None,
                       maximum: float | None = None) -> float:
        """`value`, read as `name`, as a float if it is a finite number within the bounds;
        else a ConfigError naming `name`."""
        if not _is_number(value):
            raise self.error(name, f'must be a number, got {value!r}')
        if not _is_finite(value):
            raise self.error(name, f'must be finite, got {value!r}')
        value = float(value)
        if positive and value <= 0.0:
            raise self.error(name, f'must be positive, got {value!r}')
        if non_negative and value < 0.0:
            raise self.error(name, f'must not be negative, got {value!r}')
        if minimum is not None and value < minimum:
            raise self.error(name, f'must be at least {minimum:g}, got {value!r}')
        if maximum is not None and value > maximum:
            raise self.error(name, f'must be at most {maximum:g}, got {value!r}')
        return value

    def integer(self, name: str, default: Any = ..., *, minimum: int | None = None,
                maximum: int | None = None) -> int:
        if minimum is not None or maximum is not None:
            self.bounds[self.key(name)] = Bounds(minimum, maximum)
        value = self.raw(name, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(name, f'must be an integer, got {value!r}')
        # every setting is also a ROS parameter (cdpr_control.setup.settings)
        if not INT64_MIN <= value <= INT64_MAX:
            raise self.error(name, f'must fit in 64 bits, as a ROS parameter, got {value!r}')
        if minimum is not None and value < minimum:
            raise self.error(name, f'must be at least {minimum}, got {value!r}')
        if maximum is not None and value > maximum:
            raise self.error(name, f'must be at most {maximum}, got {value!r}')
        return value

    def string(self, name: str, default: Any = ..., *, choices: tuple[str, ...] = ()) -> str:
        if choices:
            self.bounds[self.key(name)] = Bounds(choices=tuple(choices))
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise self.error(name, f'must be a string, got {value!r}')
        if choices and value not in choices:
            raise self.error(name, f'must be one of {", ".join(choices)}, got {value!r}')
        return value

    def per_cable(self, name: str, cable_count: int, *, positive: bool = False,
                  non_negative: bool = False) -> np.ndarray:
        """One number per cable (or its motor): a number, the same for each of the
        `cable_count`, or a list of one per cable; each bounded as number() bounds it."""
        bounds = dict(positive=positive, non_negative=non_negative)
        self._keep_bounds(name, **bounds)
        value = self.raw(name)
        if not isinstance(value, (list, tuple)):
            return np.full(cable_count, self._checked_number(name, value, **bounds))
        if len(value) != cable_count:
            raise self.error(name, f'must be a number or a list of {cable_count} numbers, one per cable, '
                             f'got {value!r}')
        return np.array([self._checked_number(f'{name}[{i}]', entry, **bounds) for i, entry in enumerate(value)])

    def vector(self, name: str, length: int, default: Any = ...) -> np.ndarray:
        return self._array(self.key(name), self.raw(name, default), (length,))

    def numbers(self, name: str) -> np.ndarray:
        """A non-empty list of finite numbers, of any length."""
        value = self.raw(name)
        if not isinstance(value, (list, tuple)) or not value:
            raise self.error(name, f'must be a non-empty list of numbers, got {value!r}')
        return self._array(self.key(name), value, (len(value),))

    def matrix(self, name: str, columns: int) -> np.ndarray:
        value = self.raw(name)
        if not isinstance(value, (list, tuple)) or not value:
            raise self.error(name, 'must be a non-empty list of rows')
        rows = [self._array(f'{self.key(name)}[{i}]', row, (columns,))
                for i, row in enumerate(value)]
        return np.array(rows)

    def _array(self, key: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
        # Element by element, as number() does: numpy alone would read True as 1.0 and
        # '2' as 2.0.
        if (not isinstance(value, (list, tuple)) or len(value) != shape[0]
                or not all(map(_is_number, value))):
            raise ConfigError(self.path, key, f'must be a list of {shape[0]} numbers, got {value!r}')
        if not all(map(_is_finite, value)):
            raise ConfigError(self.path, key, f'must hold finite numbers, got {value!r}')
        return np.array(value, dtype=float)


DEFAULTS_FOLDER = Path(__file__).with_name('defaults')


@lru_cache(maxsize=1)
def paper_defaults() -> dict:
    """Every option section, with the paper's values: the files of defaults/ together."""
    sections = {}
    for path in sorted(DEFAULTS_FOLDER.glob('*.yaml')):
        sections.update(load_yaml(path))
    return sections


@lru_cache(maxsize=1)
def default_descriptions() -> dict[str, str]:
    """Dotted key → what the defaults files' comments say of it (the comment lines just
    above the key and the one beside it), for ROS parameter descriptions."""
    descriptions = {}
    for path in sorted(DEFAULTS_FOLDER.glob('*.yaml')):
        keys: list[tuple[int, str]] = []   # (indent, key) of the mappings the line is in
        above: list[str] = []
        for line in path.read_text().splitlines():
            text = line.strip()
            if text.startswith('#'):
                above.append(text.lstrip('# '))
                continue
            if not text or ':' not in text:
                above = []
                continue
            indent = len(line) - len(line.lstrip())
            key, _, rest = text.partition(':')
            keys = [(level, name) for level, name in keys if level < indent] + [(indent, key)]
            beside = rest.partition('#')[2].strip()
            descriptions['.'.join(name for _, name in keys)] = ' '.join(above + [beside]).strip()
            above = []
    return descriptions


def with_defaults(data: dict, defaults: Mapping, prefix: str = '') -> tuple[dict, set[str]]:
    """`data` with every key of `defaults` it lacks, mappings merged key by key; and the
    dotted keys so filled in. A value the file gives (even of another type) is kept,
    for the loaders to judge."""
    merged, filled = dict(data), set()
    for key, value in defaults.items():
        dotted = f'{prefix}.{key}' if prefix else str(key)
        if key not in data:
            merged[key] = copy.deepcopy(value)   # the cached defaults stay as read
            filled.add(dotted)
            filled.update(f'{dotted}.{inner}' for inner in _dotted_keys(value))
        elif isinstance(value, Mapping) and isinstance(data[key], Mapping):
            merged[key], inner_filled = with_defaults(data[key], value, dotted)
            filled |= inner_filled
    return merged, filled


def _dotted_keys(value: Any) -> list[str]:
    if not isinstance(value, Mapping):
        return []
    return [name for key, inner in value.items()
            for name in [str(key)] + [f'{key}.{deeper}' for deeper in _dotted_keys(inner)]]


def load_config(path: str | Path) -> Section:
    """The whole YAML file at `path`; a robot file, or a robot's set-up with the robot
    file it names, with the paper's settings for every option left out."""
    data = load_yaml(path)
    sources = {}
    if 'robot_file' in data:
        setup = Section(data, path)
        if 'robot' in data:
            raise setup.error('robot_file', 'and robot: a set-up names its robot file or holds the robot, not both')
        robot_path = Path(path).parent / setup.string('robot_file')
        if not robot_path.is_file():
            raise setup.error('robot_file', f'names {robot_path}, which is not a file')
        robot = Section(load_yaml(robot_path), robot_path)
        data = {key: value for key, value in data.items() if key != 'robot_file'}
        data['robot'] = robot.raw('robot')
        sources['robot'] = str(robot_path)
    if 'robot' not in data:
        return Section(data, path)
    merged, filled = with_defaults(data, paper_defaults())
    return Section(merged, path, defaulted=frozenset(filled), sources=sources)


def load_section(path: str | Path, name: str) -> Section:
    """The top-level section `name` of the YAML file at `path`."""
    return load_config(path).section(name)


def resolve_config(name_or_path: str | Path, folders: list[Path]) -> Path:
    """An existing path as given, else that path (or, failing that, its file name) in the
    first of `folders` (the caller's shipped configs) that holds it; a name without a
    suffix is also looked for as NAME.yaml (`--config paper_rig`)."""
    path = Path(name_or_path)
    if path.exists():
        return path
    names = [path] + ([path.with_name(path.name + '.yaml')] if not path.suffix else [])
    for candidate in ([folder / name for name in names for folder in folders]
                      + [folder / name.name for name in names for folder in folders]):
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(f'no config {name_or_path!s} (looked in {", ".join(map(str, folders)) or "no folder"})')
