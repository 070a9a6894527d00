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

    def load_all(self) -> 'Kernel':
        """Every function ready to call now (CPython's are), so that a realtime loop's
        first tick does not wait for one; the kernel itself."""
        return self


def python_kernel(*functions: Callable, **attributes) -> Kernel:
    """The `python` kernel of `functions`, as CPython runs them."""
    return Kernel('python', {function.__name__: function for function in functions}, **attributes)


class CompiledKernel(Kernel):
    """The `compiled` kernel: each function compiled by numba when first used (a process
    loads, or compiles, only what it calls: each costs ~0.1 s to load from the cache and
    seconds to compile), for exactly the types of its signature (a call with others is an
    error, not a silent compile of seconds in a realtime loop), and cached once per
    installation (`make setup` compiles them all, `load_all`)."""

    def __init__(self, numba, signatures: dict, **attributes):
        super().__init__('compiled', {}, **attributes)
        self._numba = numba
        self._signatures = {function.__name__: (function, signature) for function, signature in signatures.items()}

    def __getattr__(self, name: str):
        # called only for an attribute not set yet: a function not compiled yet
        if name.startswith('_') or name not in self._signatures:
            raise AttributeError(name)
        function, signature = self._signatures[name]
        compiled = self._numba.njit(signature, cache=True)(function)
        setattr(self, name, compiled)
        return compiled

    def load_all(self) -> 'Kernel':
        """Every function compiled, or loaded from the cache (~0.1 s each), now: so that a
        realtime loop's first tick does not wait for one; the kernel itself."""
        for name in self._signatures:
            getattr(self, name)
        return self


def compiled_kernel(helpers, signatures: Callable, **attributes) -> CompiledKernel | None:
    """The `compiled` kernel of the functions of `signatures(numba.types)` (function →
    numba signature); the `helpers` they call are compiled into each. None where numba
    is not installed.

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
    return CompiledKernel(numba, signatures(numba.types), **attributes)


def choose(name: str, python: Kernel, compiled: Callable[[], Kernel | None]) -> Kernel:
    """The kernel called `name` (KERNELS); 'compiled' is the Python one where numba is
    not installed. `compiled` builds (or returns the cached) compiled kernel."""
    if name not in KERNELS:
        raise ValueError(f'kernel must be one of {", ".join(KERNELS)}, got {name!r}')
    return (name == 'compiled' and compiled()) or python
