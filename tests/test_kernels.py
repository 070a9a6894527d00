"""Each module written once for CPython and numba (cdpr_control.kernels) gives its
compiled functions by the name `compiled` and the CPython ones by `python`, names the
choices on a wrong one, and both give the same numbers. The simulation's kernels are
compared on whole runs in their own files (test_elastic_substeps, test_platform_substeps,
test_point_mass_substeps); the per-tick ones of the controller and the supervisor here."""
from __future__ import annotations

import importlib

import numpy as np
import pytest

from cdpr_control import kernels
from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.point_mass import substeps as point_mass_substeps
from cdpr_control.control import tracking
from cdpr_control.tension_distribution import active_set
from cdpr_control.tension_distribution import InfeasibleTensionError
from cdpr_control.tension_distribution.bounded_minimum_norm import BoundedMinimumNorm
from cdpr_fdi.detection import tick_arithmetic
from cdpr_twin.models import elastic_substeps

pytest.importorskip('numba')

MODULES = (elastic_substeps, platform_substeps, point_mass_substeps, tracking, tick_arithmetic, active_set)
MOTORS = 8


@pytest.mark.parametrize('module', MODULES, ids=lambda module: module.__name__.rsplit('.', 1)[-1])
def test_compiled_is_built_from_this_source_and_python_is_cpython(module, monkeypatch):
    """`make setup` builds every kernel module ahead of time: `compiled` is that build,
    with a function for each of CPython's; without it, numba compiles the very functions
    CPython runs."""
    compiled, python = module.kernel('compiled'), module.kernel('python')
    assert compiled.name == 'compiled' and python is module.PYTHON and compiled is not python
    built = kernels.ahead_of_time(module)
    assert built is not None, f'{module.__name__} not built ahead of time: make setup builds it'
    functions = {name: function for name, function in vars(python).items() if callable(function) and name != 'view'}
    for name in functions:
        assert getattr(compiled, name) is getattr(built, name), name
    monkeypatch.setattr(kernels, 'ahead_of_time', lambda module: None)
    just_in_time = kernels.compiled_kernel(module.__name__)
    assert {name: function for name, (function, _) in just_in_time.sources().items()} == functions
    with pytest.raises(ValueError, match='kernel must be one of compiled, python'):
        module.kernel('fortran')


SMALL_KERNEL_MODULE = """
from cdpr_control.kernels import chooser, python_kernel


def scaled(values, factor, out):
    for i in range(values.shape[0]):
        out[i] = factor * values[i]


HELPERS = ()
PYTHON = python_kernel(scaled)


def signatures(types):
    row = types.float64[::1]
    return {scaled: types.void(row, types.float64, row)}


kernel = chooser(__name__, PYTHON)
"""


def test_a_kernel_built_from_an_earlier_source_is_not_loaded(tmp_path, monkeypatch):
    """The build is found by its source's hash: once the source changes, the kernel is
    numba's again until the next build, never machine code of another source."""
    source = tmp_path / 'small_kernel.py'
    source.write_text(SMALL_KERNEL_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module('small_kernel')
    assert kernels.ahead_of_time(module) is None
    assert kernels.main(['small_kernel']) == 0
    built = kernels.ahead_of_time(module)
    assert built is not None and module.kernel().scaled is built.scaled
    doubled = np.empty(3)
    built.scaled(np.arange(3.0), 2.0, doubled)
    assert doubled.tolist() == [0.0, 2.0, 4.0]
    source.write_text(SMALL_KERNEL_MODULE + '# edited\n')
    assert kernels.ahead_of_time(module) is None


def both(module, function: str, *arguments, outputs: int):
    """`function` of both kernels on copies of `arguments` and `outputs` fresh rows:
    (python's outputs and result, compiled's)."""
    results = []
    for name in ('python', 'compiled'):
        copies = [argument.copy() if isinstance(argument, np.ndarray) else argument for argument in arguments]
        written = [np.full(MOTORS, np.nan) for _ in range(outputs)]
        returned = getattr(module.kernel(name), function)(*copies, *written)
        results.append((copies, written, returned))
    return results


def test_the_per_tick_kernels_give_the_same_numbers_with_both():
    rng = np.random.default_rng(3)
    rows = [rng.normal(0.0, 2.0, MOTORS) for _ in range(6)]
    broken = (rng.random(MOTORS) < 0.3).astype(float)
    motor = np.array([1.2e-4, 1.5e-3, 0.036, 0.1, 0.1])
    checks = [
        both(tracking, 'tracking_torques', 24.0, 0.7, 1.5, *rows[:5], broken, outputs=1),
        both(tick_arithmetic, 'sensorless_tensions', motor, *rows[:3], 0.002, outputs=3),
        both(tick_arithmetic, 'reference_tensions', motor, 0.002, *rows[:3], outputs=1),
    ]
    recent, total = rng.normal(0.0, 1.0, (5, 3, MOTORS)), rng.normal(0.0, 5.0, (3, MOTORS))
    checks.append(both(tick_arithmetic, 'collapse_window', recent, total, 2, *rows[:3], 0.5, 1.0, np.full(1, -np.inf),
                       outputs=1))
    for (python_in, python_out, python_result), (compiled_in, compiled_out, compiled_result) in checks:
        assert python_result == compiled_result
        for python, compiled in zip(python_in + python_out, compiled_in + compiled_out):
            if isinstance(python, np.ndarray):
                assert np.array_equal(python, compiled) and not np.isnan(python).any()
    torques = checks[0][0][1][0]
    assert np.all(torques[broken != 0.0] == 0.0) and np.all(np.abs(torques) <= 1.5)


def test_the_per_tick_kernels_take_the_read_only_arrays_messages_give():
    """A message's arrays are read-only views of its buffer: the controller and the
    supervisor hand them to the compiled kernels as they are."""
    def read_only(values):
        array = np.frombuffer(np.asarray(values, dtype=float).tobytes())
        assert not array.flags.writeable
        return array
    motors = [read_only(np.linspace(-1.0, 1.0, MOTORS) * k) for k in (1, 2, 3)]
    torque = np.empty(MOTORS)
    tracking.kernel('compiled').tracking_torques(24.0, 0.7, 1.5, *motors, motors[0], motors[1],
                                                 read_only(np.zeros(MOTORS)), torque)
    assert np.all(np.isfinite(torque))
    tension, low, high = np.empty(MOTORS), np.empty(MOTORS), np.empty(MOTORS)
    tick_arithmetic.kernel('compiled').sensorless_tensions(read_only([1.2e-4, 1.5e-3, 0.036, 0.1, 0.1]), *motors,
                                                           0.002, tension, low, high)
    assert np.all(low <= high) and np.all((tension == low) | (tension == high))


def test_the_motor_watch_keeps_the_runs_the_supervisor_defines():
    """watch_unloaded and watch_freed, on both kernels, tick by tick against the
    supervisor's definitions written as array expressions: a motor's run above δ, its
    last tick above δ, its drop to looking free (δ/ρ or more down from the larger of the
    two periods before) and its first tick looking free while losing its pull."""
    rng = np.random.default_rng(5)
    delta_nm, radius_m = 0.1, 0.036
    delta_n = delta_nm / radius_m
    # residuals about δ and τ̂ about δ/ρ, with jumps: every branch taken many times
    residuals = rng.normal(delta_nm, 0.08, (400, MOTORS))
    lows = rng.normal(delta_n, 2.0, (400, MOTORS)) + 6.0 * (rng.random((400, MOTORS)) < 0.1)
    unloaded_since, last_unloaded = np.full(MOTORS, -1), np.full(MOTORS, -10**9)
    dropped_since, freed_since, recent = np.full(MOTORS, -1), np.full(MOTORS, -1), np.full((2, MOTORS), -np.inf)
    kernel_state = {name: [np.zeros(MOTORS), unloaded_since.copy(), last_unloaded.copy(), recent.copy(),
                           dropped_since.copy(), freed_since.copy()] for name in ('python', 'compiled')}
    counts = np.zeros(4, dtype=int)
    for tick, (residual, low) in enumerate(zip(residuals, lows)):
        unloaded = residual > delta_nm
        unloaded_since = np.where(unloaded, np.where(unloaded_since < 0, tick, unloaded_since), -1)
        last_unloaded = np.where(unloaded, tick, last_unloaded)
        free = low * radius_m < delta_nm
        dropped = recent.max(axis=0) - low >= delta_n
        dropped_since = np.where(free, np.where((dropped_since < 0) & dropped, tick, dropped_since), -1)
        recent = np.array([recent[1], low])
        lost = unloaded_since >= 0
        freed_since = np.where((freed_since < 0) & free & (lost | (dropped_since == tick)), tick,
                               np.where(~free & ~lost, -1, freed_since))
        counts += [unloaded.sum(), (dropped_since == tick).sum(), (freed_since == tick).sum(),
                   ((freed_since >= 0) & ~free).sum()]
        for name, (flags, since, last, window, drops, frees) in kernel_state.items():
            arithmetic = tick_arithmetic.kernel(name)
            arithmetic.watch_unloaded(residual, delta_nm, tick, flags, since, last)
            arithmetic.watch_freed(low, radius_m, delta_nm, delta_n, tick, window, since, drops, frees)
            assert np.array_equal(flags != 0.0, unloaded) and np.array_equal(since, unloaded_since), (name, tick)
            assert np.array_equal(last, last_unloaded) and np.array_equal(window, recent), (name, tick)
            assert np.array_equal(drops, dropped_since) and np.array_equal(frees, freed_since), (name, tick)
    assert np.all(counts > 20), counts


def test_the_active_set_search_gives_the_same_projection_with_both():
    """bounded_minimum_norm's dual active-set search on random cables and wrenches, both
    kernels: the same point, to the bit, or the same constraint out of reach; and the point
    is the projection (its bounds hold, and no feasible z is nearer z_ref)."""
    rng = np.random.default_rng(11)
    statuses = set()
    for _ in range(200):
        rows = int(rng.choice([3, 6]))
        cables = rows + int(rng.integers(1, 6))
        structure = rng.normal(size=(rows, cables))
        particular = np.linalg.pinv(structure) @ (rng.normal(size=rows) * rng.uniform(1.0, 30.0))
        null_basis = np.linalg.svd(structure)[2][rows:].T
        low, high = rng.uniform(0.0, 5.0), rng.uniform(20.0, 60.0)
        normals = np.ascontiguousarray(np.vstack([null_basis, -null_basis]))
        bounds = np.concatenate([low - particular, particular - high])
        start = null_basis.T @ (np.full(cables, rng.uniform(low, high)) - particular)
        found = []
        for name in ('python', 'compiled'):
            z, failed = start.copy(), np.zeros(1, dtype=np.intp)
            status = active_set.kernel(name).project(normals, bounds, z, 1e-9, 1e-12, 10 * cables + 10, failed)
            found.append((status, z, int(failed[0]) if status == active_set.UNREACHABLE else None))
        (status, z, failed), (compiled_status, compiled_z, compiled_failed) = found
        assert status == compiled_status and failed == compiled_failed and np.array_equal(z, compiled_z)
        statuses.add(status)
        if status == active_set.SETTLED:
            assert np.all(normals @ z - bounds >= -1e-9)
            # nearer points along any feasible direction from z break a bound: z is the projection
            for _ in range(20):
                nearer = z + 1e-3 * rng.normal(size=z.size)
                if np.linalg.norm(nearer - start) < np.linalg.norm(z - start) - 1e-9:
                    assert np.any(normals @ nearer - bounds < 0.0)
    assert statuses == {active_set.SETTLED, active_set.UNREACHABLE}, statuses


def test_a_bounded_minimum_norm_with_no_tensions_names_the_cable_it_cannot_bring_in():
    # three cables pulling one way along x with at least 5 N each cannot give 1 N along x
    structure = np.array([[1.0, 1.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 1.0, -1.0, 0.0]])
    with pytest.raises(InfeasibleTensionError, match='cannot be brought to') as raised:
        BoundedMinimumNorm(5.0, 50.0, 20.0).distribute(structure, np.array([1.0, 10.0, 0.0]))
    assert raised.value.cable in range(4)
