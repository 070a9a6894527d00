"""Kernels: functions written once on floats and small arrays, element by element, that
CPython runs as they are or numba compiles (elastic_substeps, platform_substeps,
point_mass_substeps, cdpr_fdi.tick_arithmetic).

On a handful of cables numpy's per-call cost is most of a computation; numba compiles
such loops to a few µs or less, for ~0.5 s of loading numba in each process that uses
one. The `python` kernel runs the same functions, for a machine without numba and to
check the compiled one against: both do the same operations in the same order.
"""
from __future__ import annotations

from typing import Callable

KERNELS = ('compiled', 'python')


class Kernel:
    """The functions of a module as one of KERNELS runs them, as attributes under their
    own names (and any other `attributes` the module's callers need)."""

    def __init__(self, name: str, functions: dict[str, Callable], **attributes):
        self.name = name
        self.__dict__.update(functions, **attributes)


def python_kernel(*functions: Callable, **attributes) -> Kernel:
    """The `python` kernel of `functions`, as CPython runs them."""
    return Kernel('python', {function.__name__: function for function in functions}, **attributes)


def compiled_kernel(helpers, signatures: Callable, **attributes) -> Kernel | None:
    """The `compiled` kernel: each function of `signatures(numba.types)` (function →
    numba signature) compiled for exactly those types (a call with others is an error,
    not a silent compile of seconds in a realtime loop) and cached once per installation
    (`make setup` does it), so that a process only loads them. The `helpers` they call
    are compiled into each. None where numba is not installed.

    numba checks a cache against the file of the function it compiled only: every
    helper must live in the file of the functions that call it.
    """
    try:
        import numba
        from numba.extending import register_jitable
    except ImportError:
        return None
    for helper in helpers:
        # callable from the compiled functions; unchanged for CPython
        register_jitable(helper)
    return Kernel('compiled', {function.__name__: numba.njit(signature, cache=True)(function)
                               for function, signature in signatures(numba.types).items()}, **attributes)


def choose(name: str, python: Kernel, compiled: Callable[[], Kernel | None]) -> Kernel:
    """The kernel called `name` (KERNELS); 'compiled' is the Python one where numba is
    not installed. `compiled` builds (or returns the cached) compiled kernel."""
    if name not in KERNELS:
        raise ValueError(f'kernel must be one of {", ".join(KERNELS)}, got {name!r}')
    return (name == 'compiled' and compiled()) or python
