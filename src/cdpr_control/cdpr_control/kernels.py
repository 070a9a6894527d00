"""Kernels: functions written once on floats and small arrays, element by element, that
CPython runs as they are or numba compiles (elastic_substeps, platform_substeps,
point_mass_substeps, tension_distribution.active_set, cdpr_fdi.detection.tick_arithmetic).

On a handful of cables numpy's per-call cost is most of a computation; numba compiles
such loops to a few µs or less. The `python` kernel runs the same functions, for a
machine without numba and to check the compiled one against: both do the same
operations in the same order.

The `compiled` kernel of a module is, in this order:
- its extension module built ahead of time from this very source (`make setup` runs
  `python -m cdpr_control.kernels MODULE...`, numba's pycc and the C compiler), kept in
  the package's `__pycache__` under the source's hash: it loads in under a millisecond
  without numba, where loading numba and the cached machine code costs each process
  ~0.6 s of CPU and ~100 MB (every node of the loop, at every start);
- else numba's just-in-time compilation, cached (a colcon workspace's install, an edited
  source until the next `make setup`);
- else, without numba, the Python one.
A kernel module names the functions numba compiles and their types in
`signatures(numba.types)` (function → signature), the functions they call in `HELPERS`,
its Python kernel `PYTHON = python_kernel(...)`, and gets its `kernel` from `chooser`.
"""
from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.machinery
import importlib.util
import multiprocessing
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
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
    """The `compiled` kernel where none was built ahead of time: each function compiled by
    numba when first used (a process loads, or compiles, only what it calls: each costs
    ~0.1 s to load from the cache and seconds to compile), for exactly the types of its
    signature (a call with others is an error, not a silent compile of seconds in a
    realtime loop), and cached."""

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

    def sources(self) -> dict:
        """Per function name, (the function compiled, its numba signature)."""
        return dict(self._signatures)

    def load_all(self) -> 'Kernel':
        """Every function compiled, or loaded from the cache (~0.1 s each), now: so that a
        realtime loop's first tick does not wait for one; the kernel itself."""
        for name in self._signatures:
            getattr(self, name)
        return self


def compiled_kernel(module_name: str, **attributes) -> Kernel | None:
    """The `compiled` kernel of the kernel module `module_name`: built ahead of time from
    its source, else compiled by numba when first used; None where numba is not installed.

    Both check what they run against the file of the compiled functions only (its hash,
    numba's cache its time stamp): every helper must live in that file.
    """
    module = sys.modules[module_name]
    built = ahead_of_time(module)
    if built is not None:
        return Kernel('compiled', {name: getattr(built, name) for name in dir(built) if not name.startswith('_')},
                      **attributes)
    try:
        import numba
    except ImportError:
        return None
    _register_helpers(module)
    return CompiledKernel(numba, module.signatures(numba.types), **attributes)


def _register_helpers(module) -> None:
    from numba.extending import register_jitable
    for helper in module.HELPERS:
        # callable from the compiled functions; unchanged for CPython
        register_jitable(helper)


def _ahead_of_time_path(module) -> tuple[str, Path]:
    """(the extension's module name, its file) for the source of `module` as it is now."""
    source = Path(module.__file__)
    digest = hashlib.sha256(source.read_bytes()).hexdigest()[:16]
    # named by the whole module path: two rooms hold a `substeps` module each
    name = f"{module.__name__.replace('.', '_')}_ahead_of_time"
    return name, source.parent / '__pycache__' / f'{name}.{digest}{importlib.machinery.EXTENSION_SUFFIXES[0]}'


def ahead_of_time(module):
    """The extension module built from the source of `module` as it is now, or None (also
    where it cannot be loaded: built against other libraries than this environment's)."""
    name, path = _ahead_of_time_path(module)
    if not path.is_file():
        return None
    spec = importlib.util.spec_from_file_location(name, path)
    built = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(built)
    except ImportError:
        return None
    return built


def build_ahead_of_time(module_name: str) -> str:
    """Build the extension of the kernel module `module_name` (numba's pycc, the C
    compiler) beside its source, replacing any built from an earlier source; what was
    done ('' where it was built already)."""
    module = importlib.import_module(module_name)
    name, path = _ahead_of_time_path(module)
    if path.is_file():
        return ''
    import warnings

    from numba import types
    from numba.core.errors import NumbaPendingDeprecationWarning
    with warnings.catch_warnings():
        # pycc is numba's ahead-of-time compiler, deprecated without a successor yet
        warnings.simplefilter('ignore', NumbaPendingDeprecationWarning)
        from numba.pycc import CC
    _register_helpers(module)
    compiler = CC(name)
    compiler.output_dir = str(path.parent)
    compiler.output_file = path.name
    for function, signature in module.signatures(types).items():
        compiler.export(function.__name__, signature)(function)
    path.parent.mkdir(exist_ok=True)
    for earlier in path.parent.glob(f'{name}.*'):
        earlier.unlink()
    compiler.compile()
    return f'{module_name}: kernels built ahead of time'


def main(argv=None) -> int:
    """Build the extensions of the kernel modules named, two at a time, those not built
    from their current source yet (a C compiler is needed: where the build fails, numba
    compiles the kernels at first use instead)."""
    names = sys.argv[1:] if argv is None else argv
    # fresh processes, not forks: a caller with threads of its own (a test session's, a
    # node's) leaves a fork only the forking thread, and once a forked builder crashed in
    # its garbage collector
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context('spawn')) as pool:
        for outcome in pool.map(_build_or_say, names):
            if outcome:
                print(outcome)
    return 0


def _build_or_say(module_name: str) -> str:
    try:
        return build_ahead_of_time(module_name)
    except Exception as err:   # any compiler or toolchain failure leaves the JIT path
        return f'{module_name}: not built ahead of time ({type(err).__name__}: {err}); numba compiles it at first use'


if __name__ == '__main__':
    sys.exit(main())


def chooser(module_name: str, python: Kernel, **attributes) -> Callable[..., Kernel]:
    """A kernel module's `kernel(name='compiled')`: its kernel called `name` (KERNELS),
    `python` its Python one. The compiled one (compiled_kernel, with `attributes`) is
    built or loaded once per process, and only by a process that asks for it; where numba
    is not installed, 'compiled' is the Python one."""
    compiled = functools.cache(lambda: compiled_kernel(module_name, **attributes))

    def kernel(name: str = 'compiled') -> Kernel:
        if name not in KERNELS:
            raise ValueError(f'kernel must be one of {", ".join(KERNELS)}, got {name!r}')
        return (name == 'compiled' and compiled()) or python

    return kernel
