"""Bounded tension distribution: the tensions closest to a reference within the bounds.

Solves  min ½‖τ − τ_ref‖²  s.t.  S τ = w,  τ_min ≤ τ ≤ τ_max.  Every τ with S τ = w is
τ = τ₀ + N z (τ₀ = S⁺ w, N an orthonormal basis of the null space of S), and the
objective becomes ½‖z − z_ref‖², so the problem is the projection of z_ref onto the
polytope the bounds cut out of the null space. Goldfarb and Idnani's dual active-set
method solves it exactly in a finite number of steps, or proves that no tensions
exist. With τ_ref = 0 the result equals the paper's S⁺ w whenever that is within the
bounds; with τ_ref = (τ_min + τ_max)/2 it is the improved closed-form method.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.tension_distribution.active_set import SETTLED, SINGULAR, UNREACHABLE, kernel as active_set_kernel
from cdpr_control.tension_distribution.base import BOUND_TOLERANCE_N, FreeDirection, InfeasibleTensionError, TensionDistribution, minimum_norm

DIRECTION_TOLERANCE = 1e-12


class BoundedMinimumNorm(TensionDistribution):

    name = 'bounded_minimum_norm'

    def __init__(self, tension_min_n: float, tension_max_n: float, reference_tension_n: float = 0.0):
        super().__init__(tension_min_n, tension_max_n)
        self.reference_tension_n = float(reference_tension_n)

    def distribute(self, structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
        count = structure.shape[1]
        reference = np.full(count, self.reference_tension_n)
        tensions = reference + minimum_norm(structure, wrench_n - structure @ reference)
        if not self._outside_bounds(tensions):
            return tensions
        return self._projection(structure, wrench_n, reference)

    def distribute_each(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`distribute` of every row (NaN where none), the closed form for the whole stack at
        once: only the rows it leaves outside the bounds are projected, one by one."""
        return self._stack(structures, wrenches_n, first_infeasible_raises=False)

    def distribute_rows(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """As the base class's, without projecting the rows after the first infeasible one
        (a recovery plan that does not fit is tried again slower: its rest is not needed)."""
        return self._stack(structures, wrenches_n, first_infeasible_raises=True)

    def _stack(self, structures, wrenches_n, first_infeasible_raises: bool) -> np.ndarray:
        reference = np.full(structures.shape[:-2] + structures.shape[-1:], self.reference_tension_n)
        try:
            tensions = reference + minimum_norm(
                structures, wrenches_n - np.einsum('...ij,...j->...i', structures, reference))
        except InfeasibleTensionError:
            # a row whose cables span too little: the others are still answered
            return (super().distribute_rows if first_infeasible_raises
                    else super().distribute_each)(structures, wrenches_n)
        outside = np.flatnonzero(self._outside_bounds(tensions))
        if outside.size and structures.shape[-1] - structures.shape[-2] == 1:
            tensions[outside] = self._interval_projection(FreeDirection.of(structures[outside], wrenches_n[outside]),
                                                          reference[outside])
            outside = outside[np.isnan(tensions[outside]).any(axis=-1)]
            if not first_infeasible_raises:
                return tensions
            # the active-set search names why the first row has none (and settles a row
            # the interval left out by rounding alone)
        if outside.size:
            projected = self._projections(structures[outside], wrenches_n[outside], reference[outside],
                                          stop_at_failure=first_infeasible_raises)
            for row, (projection, failure) in zip(outside, projected):
                if failure is not None and first_infeasible_raises:
                    raise failure.in_row(int(row))
                tensions[row] = np.nan if failure is not None else projection
        return tensions

    def distribute_along(self, free: FreeDirection, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`distribute_each` from the stack's free direction: the closed form is τ₀ plus
        the reference's share along n (τ_ref + S⁺(w − S τ_ref) = τ₀ + n nᵀ τ_ref), the
        rows it leaves outside the bounds projected on their interval."""
        reference = np.full(free.particular.shape, self.reference_tension_n)
        tensions = free.particular + np.einsum('ij,ij->i', free.null, reference)[:, None] * free.null
        outside = np.flatnonzero(self._outside_bounds(tensions))
        if outside.size:
            tensions[outside] = self._interval_projection(free.rows(outside), reference[outside])
        return tensions

    def _interval_projection(self, free: FreeDirection, references):
        """`_projection` of each row of a stack whose cables leave a null space of one
        dimension (`free`), at once (NaN where none): there the polytope is an interval
        of z, and the projection z_ref clipped to it."""
        particular, null = free.particular, free.null
        low, high = free.interval(self.tension_min_n, self.tension_max_n)
        z = np.clip(np.einsum('ij,ij->i', null, references - particular), low, high)
        tensions = particular + z[:, None] * null
        held = (low <= high) & ~self._outside_bounds(tensions)
        return np.where(held[:, None], tensions, np.nan)

    def _projection(self, structure, wrench_n, reference):
        [(tensions, failure)] = self._projections(structure[None], wrench_n[None], reference[None],
                                                  stop_at_failure=True)
        if failure is not None:
            raise failure
        return tensions

    def _projections(self, structures, wrenches_n, references, stop_at_failure: bool):
        """Per row of a stack, (its tensions, None), or (None, the InfeasibleTensionError
        saying why none); with `stop_at_failure`, no row after the first that has none. S⁺ w and
        the null bases of the whole stack at once (numpy's per-call cost, not the
        arithmetic, is most of a row's), then the compiled search row by row."""
        count = structures.shape[-1]
        particular = minimum_norm(structures, wrenches_n)
        null_bases = np.swapaxes(np.linalg.svd(structures)[2][:, structures.shape[-2]:], -1, -2)
        # Constraints normal · z ≥ bound: τ₀ + N z ≥ τ_min, then −(τ₀ + N z) ≥ −τ_max.
        # C order, as the kernel reads it: stacked from the transposed bases, it is Fortran's
        normals = np.ascontiguousarray(np.concatenate([null_bases, -null_bases], axis=-2))
        bounds = np.ascontiguousarray(np.concatenate([self.tension_min_n - particular,
                                                      particular - self.tension_max_n], axis=-1))
        z = np.ascontiguousarray((np.swapaxes(null_bases, -1, -2) @ (references - particular)[..., None])[..., 0])
        search, failed = active_set_kernel(), np.zeros(1, dtype=np.intp)
        results = []
        for row in range(len(structures)):
            status = search.project(normals[row], bounds[row], z[row], BOUND_TOLERANCE_N, DIRECTION_TOLERANCE,
                                    10 * count + 10, failed)
            if status == SETTLED:
                results.append((particular[row] + null_bases[row] @ z[row], None))
                continue
            if status == UNREACHABLE:
                bound = self.tension_min_n if failed[0] < count else self.tension_max_n
                failure = InfeasibleTensionError(
                    f'cannot be brought to {bound} N while the others keep within their bounds',
                    cable=int(failed[0]) % count)
            elif status == SINGULAR:
                raise np.linalg.LinAlgError('the active bounds of the dual active-set search are dependent')
            else:
                failure = InfeasibleTensionError('the dual active-set search did not settle')
            results.append((None, failure))
            if stop_at_failure:
                break
        return results
