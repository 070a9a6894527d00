"""Each module written once for CPython and numba (cdpr_control.kernels) gives its
compiled functions by the name `compiled` and the CPython ones by `python`, and names the
choices on a wrong one. Whether the two give the same numbers is tested module by module
(test_elastic_substeps, test_platform_substeps, test_point_mass_substeps)."""
from __future__ import annotations

import pytest

from cdpr_control import platform_substeps, point_mass_substeps
from cdpr_twin import elastic_substeps

pytest.importorskip('numba')


@pytest.mark.parametrize('module', (elastic_substeps, platform_substeps, point_mass_substeps),
                         ids=lambda module: module.__name__.rsplit('.', 1)[-1])
def test_compiled_is_numba_and_python_is_cpython(module):
    compiled, python = module.kernel('compiled'), module.kernel('python')
    assert compiled.name == 'compiled' and python is module.PYTHON and compiled is not python
    for name, function in vars(python).items():
        if callable(function) and name != 'view':
            # a numba dispatcher compiled from the very function CPython runs
            assert getattr(compiled, name).py_func is function, name
    with pytest.raises(ValueError, match='kernel must be one of compiled, python'):
        module.kernel('fortran')
