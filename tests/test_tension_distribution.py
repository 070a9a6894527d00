"""Tension distribution against numpy's pseudo-inverse and scipy's LP/QP solvers."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog, lsq_linear, minimize

from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.point_mass.kinematics import structure_matrix
from cdpr_control.tension_distribution import (BoundedMinimumNorm, FlooredLeastSquares, InfeasibleTensionError,
                                               make_tension_distribution, minimum_norm)
from conftest import load_robot, random_positions, random_unit_vectors


def _cases(robot, rng, count, max_acceleration):
    """(S, w) for random poses and random accelerations up to `max_acceleration` m/s²."""
    positions = random_positions(robot, rng, count, margin_m=0.05)
    accelerations = (random_unit_vectors(rng, count)
                     * max_acceleration * rng.random(count)[:, None])
    for p, a in zip(positions, accelerations):
        s, _ = structure_matrix(robot, p)
        yield p, s, robot.mass_kg * (a - robot.gravity_m_s2)


def _lp_feasible(s, w, low, high):
    result = linprog(np.zeros(s.shape[1]), A_eq=s, b_eq=w, bounds=[(low, high)] * s.shape[1],
                     method='highs')
    assert result.status in (0, 2), result.message
    return result.status == 0


def _qp_reference(s, w, low, high, reference):
    """min ½‖τ − τ_ref‖² s.t. S τ = w, low ≤ τ ≤ high, solved through its dual.

    τ(λ) = clip(τ_ref + Sᵀλ, low, high) minimises the Lagrangian over the box; the dual
    g(λ) = ½‖τ(λ) − τ_ref‖² − λᵀ(S τ(λ) − w) is concave and C¹ in the 3 unknowns λ with
    ∇g = w − S τ(λ), so scipy's BFGS finds λ and the primal optimum is τ(λ).
    """
    def tensions(lam):
        return np.clip(reference + s.T @ lam, low, high)

    def negative_dual(lam):
        t = tensions(lam)
        return -(0.5 * np.sum((t - reference) ** 2) - lam @ (s @ t - w)), -(w - s @ t)

    result = minimize(negative_dual, np.zeros(3), jac=True, method='BFGS',
                      options={'gtol': 1e-11, 'maxiter': 2000})
    t = tensions(result.x)
    assert np.linalg.norm(s @ t - w) < 1e-6 * max(1.0, np.linalg.norm(w)), result.message
    return t


def _kkt_certificate_exists(s, tensions, low, high, reference, tol=1e-7):
    """An LP, independent of the method under test: τ − τ_ref = Sᵀλ + μ_lo − μ_hi with
    μ_lo ≥ 0 only where τ = low and μ_hi ≥ 0 only where τ = high."""
    count = s.shape[1]
    at_low = np.abs(tensions - low) < 1e-7
    at_high = np.abs(tensions - high) < 1e-7
    # unknowns: λ (3, free), μ_lo (count), μ_hi (count)
    a_eq = np.hstack([s.T, np.eye(count), -np.eye(count)])
    b_eq = tensions - reference
    bounds = ([(None, None)] * 3 + [(0, None if f else 0) for f in at_low]
              + [(0, None if f else 0) for f in at_high])
    result = linprog(np.zeros(3 + 2 * count), A_eq=a_eq, b_eq=b_eq, bounds=bounds, method='highs')
    return result.status == 0


@pytest.mark.parametrize('method', ['pseudo_inverse', 'bounded_minimum_norm'])
def test_tensions_produce_the_wrench(robot, rng, method):
    distribution = make_tension_distribution(method, 0.0, 1e6)
    cases, produced = 30, 0
    for _, s, w in _cases(robot, rng, cases, 3.0):
        try:
            tensions = distribution.distribute(s, w)
        except InfeasibleTensionError:
            continue
        np.testing.assert_allclose(s @ tensions, w, atol=1e-9 * np.linalg.norm(w))
        produced += 1
    # below gravity's acceleration the cables hold most wrenches, even without bounds
    assert produced >= cases // 2


def test_pseudo_inverse_equals_numpy_pinv(robot, rng):
    distribution = make_tension_distribution('pseudo_inverse', robot.tension_min_n, robot.tension_max_n)
    returned = raised = 0
    for _, s, w in _cases(robot, rng, 60, 8.0):
        expected = np.linalg.pinv(s) @ w
        np.testing.assert_allclose(minimum_norm(s, w), expected, atol=1e-10)
        inside = expected.min() >= robot.tension_min_n and expected.max() <= robot.tension_max_n
        if inside:
            np.testing.assert_allclose(distribution.distribute(s, w), expected, atol=1e-10)
            returned += 1
        else:
            # never hands out tensions outside the bounds
            with pytest.raises(InfeasibleTensionError):
                distribution.distribute(s, w)
            raised += 1
    assert returned > 10 and raised > 0


def test_bounded_equals_pseudo_inverse_when_that_is_within_bounds(robot, rng):
    low, high = robot.tension_min_n, robot.tension_max_n
    bounded = make_tension_distribution('bounded_minimum_norm', low, high)
    compared = 0
    for _, s, w in _cases(robot, rng, 40, 2.0):
        expected = np.linalg.pinv(s) @ w
        if expected.min() >= low and expected.max() <= high:
            np.testing.assert_allclose(bounded.distribute(s, w), expected, atol=1e-10)
            compared += 1
    assert compared > 10


BOUNDS = {
    'nominal': lambda robot: (robot.tension_min_n, robot.tension_max_n, 0.0),
    'raised_minimum': lambda robot: (0.12 * robot.mass_kg * 9.81, robot.tension_max_n, 0.0),
    'tight_maximum': lambda robot: (robot.tension_min_n, 25.0, 0.0),
    'mid_reference': lambda robot: (robot.tension_min_n, 60.0, 0.5 * (robot.tension_min_n + 60.0)),
    'reference_10N': lambda robot: (5.0, 40.0, 10.0),
}


@pytest.mark.parametrize('bounds', list(BOUNDS), ids=list(BOUNDS))
def test_bounded_is_feasible_optimal_or_truly_infeasible(robot, rng, bounds):
    low, high, reference = BOUNDS[bounds](robot)
    distribution = make_tension_distribution('bounded_minimum_norm', low, high,
                                             reference_tension_n=reference)
    returned = raised = 0
    for _, s, w in _cases(robot, rng, 40, 6.0):
        feasible = _lp_feasible(s, w, low, high)
        try:
            tensions = distribution.distribute(s, w)
        except InfeasibleTensionError as err:
            assert not feasible, f'raised "{err}" but linprog finds tensions within bounds'
            raised += 1
            continue
        returned += 1
        assert feasible
        np.testing.assert_allclose(s @ tensions, w, atol=1e-8 * max(1.0, np.linalg.norm(w)))
        assert tensions.min() >= low - 1e-9 and tensions.max() <= high + 1e-9
        ref = np.full(s.shape[1], reference)
        qp = _qp_reference(s, w, low, high, ref)
        cost, cost_qp = (0.5 * np.sum((t - ref) ** 2) for t in (tensions, qp))
        assert cost <= cost_qp + 1e-7 * max(1.0, cost_qp)
        np.testing.assert_allclose(tensions, qp, atol=1e-5)
        assert _kkt_certificate_exists(s, tensions, low, high, ref)
    assert returned > 5, 'the sample never exercised a feasible wrench'
    assert raised + returned == 40


def test_bounded_active_set_engages(paper_robot, rng):
    """Poses where S⁺w violates the bounds but feasible tensions exist are solved, not refused."""
    low, high = paper_robot.tension_min_n, paper_robot.tension_max_n
    bounded = make_tension_distribution('bounded_minimum_norm', low, high)
    engaged = 0
    for _, s, w in _cases(paper_robot, rng, 200, 9.0):
        pinv = np.linalg.pinv(s) @ w
        if pinv.min() >= low or not _lp_feasible(s, w, low, high):
            continue
        tensions = bounded.distribute(s, w)
        assert tensions.min() >= low - 1e-9
        np.testing.assert_allclose(s @ tensions, w, atol=1e-8 * np.linalg.norm(w))
        engaged += 1
    assert engaged > 3


def test_reference_tension_shifts_the_solution(paper_robot, rng):
    """With τ_ref the result is τ_ref + S⁺(w − S τ_ref) when that is within bounds."""
    low, high = paper_robot.tension_min_n, paper_robot.tension_max_n
    cases = 20
    for reference in (5.0, 30.0):
        distribution = make_tension_distribution('bounded_minimum_norm', low, high,
                                                 reference_tension_n=reference)
        shifted = 0
        for _, s, w in _cases(paper_robot, rng, cases, 1.0):
            ref = np.full(4, reference)
            expected = ref + np.linalg.pinv(s) @ (w - s @ ref)
            if expected.min() >= low and expected.max() <= high:
                np.testing.assert_allclose(distribution.distribute(s, w), expected, atol=1e-9)
                # and it is the projection of τ_ref on {S τ = w}: the change is in row(S)
                change = expected - ref
                np.testing.assert_allclose(np.linalg.pinv(s) @ s @ change, change, atol=1e-9)
                shifted += 1
        assert shifted >= cases // 2, reference


def test_three_cables_have_one_solution(paper_robot, rng):
    low, high = paper_robot.tension_min_n, paper_robot.tension_max_n
    bounded = make_tension_distribution('bounded_minimum_norm', low, high, reference_tension_n=20.0)
    cases, solved = 20, 0
    for _, s, w in _cases(paper_robot, rng, cases, 1.0):
        s3 = s[:, :3]
        exact = np.linalg.solve(s3, w)
        if exact.min() >= low and exact.max() <= high:
            np.testing.assert_allclose(bounded.distribute(s3, w), exact, atol=1e-9)
            solved += 1
        else:
            with pytest.raises(InfeasibleTensionError):
                bounded.distribute(s3, w)
    # both outcomes judged, on a quarter of the cases at least
    assert min(solved, cases - solved) >= cases // 4


@pytest.mark.parametrize('method', ['pseudo_inverse', 'bounded_minimum_norm'])
def test_cables_spanning_a_plane_are_infeasible(method):
    distribution = make_tension_distribution(method, 0.0, 100.0)
    s = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    with pytest.raises(InfeasibleTensionError):
        distribution.distribute(s, np.array([0.0, 0.0, 10.0]))


def test_bad_names_and_bounds():
    with pytest.raises(ValueError):
        make_tension_distribution('no_such_method', 0.0, 1.0)
    with pytest.raises(ValueError):
        make_tension_distribution('pseudo_inverse', 5.0, 1.0)
    with pytest.raises(ValueError):
        make_tension_distribution('bounded_minimum_norm', -1.0, 1.0)


@pytest.mark.parametrize('method', ['pseudo_inverse', 'bounded_minimum_norm'])
def test_inverse_dynamics_error_names_the_pose(paper_robot, method):
    distribution = make_tension_distribution(method, paper_robot.tension_min_n, paper_robot.tension_max_n)
    p = np.array([0.3, 1.2, 1.0])
    # accelerating down faster than gravity needs pushing cables
    with pytest.raises(InfeasibleTensionError) as info:
        inverse_dynamics(paper_robot, distribution, p, np.zeros(3), np.array([0.0, 0.0, -15.0]))
    message = str(info.value)
    assert 'p = (' in message
    assert '(0.3000, 1.2000, 1.0000)' in message
    np.testing.assert_allclose(info.value.position_m, p)


# Wrenches on the 8-cable robot that admit tensions at least 0.1 N inside [2, 120] N
# (checked by the margin LP below), found by random search.
NEAR_BORDER_CASES = [
    ((2.38, 0.73, 2.4), (0.4, -4.0, -3.9)),
    ((0.69, 2.0, 0.26), (4.7, 0.8, -2.2)),
]


@pytest.mark.parametrize('position, acceleration', NEAR_BORDER_CASES)
def test_bounded_solves_feasible_wrench_near_the_border(eight_cable_robot, position, acceleration):
    robot = eight_cable_robot
    low, high = robot.tension_min_n, robot.tension_max_n
    s, _ = structure_matrix(robot, np.array(position))
    w = robot.mass_kg * (np.array(acceleration) - robot.gravity_m_s2)
    n = s.shape[1]
    # max margin μ with S τ = w, low + μ ≤ τ ≤ high − μ: unknowns (τ, μ)
    margin = linprog(np.r_[np.zeros(n), -1.0], A_eq=np.hstack([s, np.zeros((3, 1))]), b_eq=w,
                     A_ub=np.vstack([np.hstack([-np.eye(n), np.ones((n, 1))]),
                                     np.hstack([np.eye(n), np.ones((n, 1))])]),
                     b_ub=np.r_[np.full(n, -low), np.full(n, high)],
                     bounds=[(None, None)] * (n + 1), method='highs')
    assert margin.status == 0 and -margin.fun > 0.1
    tensions = make_tension_distribution('bounded_minimum_norm', low, high).distribute(s, w)
    np.testing.assert_allclose(tensions, _qp_reference(s, w, low, high, np.zeros(n)), atol=1e-5)


def test_bounded_rows_are_the_pseudo_inverse_to_the_bit_where_that_is_within_bounds(paper_robot, rng):
    """The default distribution keeps every figure of the paper's robot: on a stack of poses
    it returns S⁺ w itself wherever that is within the bounds, and elsewhere the feasible
    tensions a row alone gets."""
    low, high = paper_robot.tension_min_n, paper_robot.tension_max_n
    cases = list(_cases(paper_robot, rng, 200, 2.0))
    structures = np.array([s for _, s, _ in cases])
    wrenches = np.array([w for _, _, w in cases])
    closed_form = minimum_norm(structures, wrenches)
    inside = (closed_form.min(axis=1) >= low) & (closed_form.max(axis=1) <= high)
    assert 10 < inside.sum() < len(cases)
    bounded = make_tension_distribution('bounded_minimum_norm', low, high)
    feasible = [i for i in np.flatnonzero(~inside) if _lp_feasible(structures[i], wrenches[i], low, high)]
    rows = feasible + list(np.flatnonzero(inside))
    tensions = bounded.distribute_rows(structures[rows], wrenches[rows])
    np.testing.assert_array_equal(tensions[len(feasible):], closed_form[inside])
    for tension, row in zip(tensions[:len(feasible)], feasible):
        np.testing.assert_allclose(tension, bounded.distribute(structures[row], wrenches[row]), atol=1e-12)
        assert low - 1e-9 <= tension.min() and tension.max() <= high + 1e-9


def test_an_infeasible_row_is_named_and_its_error_crosses_processes_whole(paper_robot):
    """A worker's error reaches the parent with its message said once (pickled by parts)."""
    import pickle
    structure, _ = structure_matrix(paper_robot, paper_robot.home_position_m)
    upward = np.array([0.0, 0.0, 1e4])   # cables cannot push
    bounded = make_tension_distribution('bounded_minimum_norm', paper_robot.tension_min_n,
                                        paper_robot.tension_max_n)
    with pytest.raises(InfeasibleTensionError) as error:
        bounded.distribute_rows(np.array([structure, structure]),
                                np.array([-paper_robot.mass_kg * paper_robot.gravity_m_s2, upward]))
    assert error.value.row == 1
    named = error.value.at(paper_robot.home_position_m)
    again = pickle.loads(pickle.dumps(named))
    assert str(again) == str(named) and str(again).count('no feasible cable tensions') == 1
    np.testing.assert_array_equal(again.position_m, named.position_m)


def test_cdpr_robots_coverage_of_the_pseudo_inverse_is_counted_right(paper_robot):
    """closed_form_coverage against numpy's pseudo-inverse and an LP, point by point."""
    from cdpr_control.point_mass.statics import closed_form_coverage
    low, high = paper_robot.tension_min_n, paper_robot.tension_max_n
    axes = [np.linspace(a, b, 5) for a, b in zip(paper_robot.workspace_min_m, paper_robot.workspace_max_m)]
    closed_form = held = 0
    for position in np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3):
        s, _ = structure_matrix(paper_robot, position)
        w = -paper_robot.weight_wrench_n
        tensions = np.linalg.pinv(s) @ w
        closed_form += bool(tensions.min() >= low and tensions.max() <= high)
        held += _lp_feasible(s, w, low, high)
    assert 0 < closed_form < held
    assert closed_form_coverage(paper_robot, points_per_axis=5) == (closed_form, held)


def test_floored_least_squares_keeps_the_method_where_it_fits_and_nears_the_wrench_elsewhere(eight_cable_robot, rng):
    """Within the bounds it is the method it wraps; outside (accelerations that ask more
    than the cables can give above their floor), every tension within them and the wrench
    missed by no less than the bounded least-squares optimum (scipy) and, the fit being
    greedy, by at most a quarter of the weight more, and in most cases by the optimum."""
    robot = eight_cable_robot
    within = make_tension_distribution('bounded_minimum_norm', robot.tension_min_n, robot.tension_max_n)
    floored = FlooredLeastSquares(within)
    excess = []
    for _, structure, wrench in _cases(robot, rng, 200, max_acceleration=15.0):
        tensions = floored.distribute(structure, wrench)
        try:
            np.testing.assert_array_equal(tensions, within.distribute(structure, wrench))
            continue
        except InfeasibleTensionError:
            pass
        assert tensions.min() >= robot.tension_min_n and tensions.max() <= robot.tension_max_n
        best = np.sqrt(2.0 * lsq_linear(structure, wrench, bounds=(robot.tension_min_n, robot.tension_max_n)).cost)
        excess.append(np.linalg.norm(structure @ tensions - wrench) - best)
    weight = robot.mass_kg * np.linalg.norm(robot.gravity_m_s2)
    assert len(excess) >= 20, f'only {len(excess)} wrenches out of reach'
    assert min(excess) >= -1e-6 and max(excess) <= 0.25 * weight and np.median(excess) <= 1e-6


def test_a_stack_is_distributed_row_by_row_as_alone_and_stops_at_its_first_infeasible_row(
        eight_cable_robot, rng, monkeypatch):
    """The floored method on a stack gives each row what that row alone gets; the bounded
    one, asked for every row of a stack (a plan), searches none after the first row no
    tensions pull: the plan is tried again, slower, and the rest is not needed."""
    robot = eight_cable_robot
    within = make_tension_distribution('bounded_minimum_norm', robot.tension_min_n, robot.tension_max_n)
    cases = list(_cases(robot, rng, 120, max_acceleration=15.0))
    structures = np.array([s for _, s, _ in cases])
    wrenches = np.array([w for _, _, w in cases])
    floored = FlooredLeastSquares(within)
    np.testing.assert_allclose(floored.distribute_each(structures, wrenches),
                               [floored.distribute(s, w) for s, w in zip(structures, wrenches)], rtol=0, atol=1e-9)
    alone = within.distribute_each(structures, wrenches)
    first = int(np.flatnonzero(np.isnan(alone).any(axis=1))[0])
    searched = []   # the structures of the rows the active-set search took up
    projections = type(within)._projections

    def spied(self, structures, *rest, **options):
        results = projections(self, structures, *rest, **options)
        searched.extend(structures[:len(results)])
        return results

    monkeypatch.setattr(type(within), '_projections', spied)
    with pytest.raises(InfeasibleTensionError) as error:
        within.distribute_rows(structures, wrenches)
    assert error.value.row == first
    rows = [next(row for row, structure in enumerate(structures) if np.array_equal(structure, seen))
            for seen in searched]
    assert max(rows) == first


@pytest.mark.parametrize('kernel', ['compiled', 'python'])
def test_the_nearest_wrench_within_the_bounds_is_scipys_bounded_least_squares(rng, kernel):
    """A platform's seven cables (6 × 7 structure matrices, moments weighted as a steered
    approach weighs them): within the bounds, the weighted misfit of the wrench is
    scipy's optimum to 1e-7 of the problem's scale; where the wrench can be pulled
    exactly, it is. Both kernels of the one source (platform_substeps.nearest_wrench)."""
    from cdpr_control.platform.substeps import kernel as platform_kernel
    nearest_wrench = platform_kernel(kernel).nearest_wrench
    exact = 0
    for _ in range(300 if kernel == 'compiled' else 30):
        structure = rng.normal(size=(6, 7))
        wrench = rng.normal(size=6) * rng.choice([3.0, 30.0, 300.0])
        weights = np.array([1.0, 1.0, 1.0] + [rng.uniform(1.0, 100.0)] * 3)
        tension = np.empty(7)
        assert nearest_wrench(np.ascontiguousarray(structure.T), wrench, weights, 4.0, 120.0, tension) >= 0
        assert tension.min() >= 4.0 - 1e-9 and tension.max() <= 120.0 + 1e-9
        reference = lsq_linear(weights[:, None] * structure, weights * wrench, bounds=(4.0, 120.0),
                               method='bvls', tol=1e-12).x

        def misfit(t):
            return float(np.sum((weights * (structure @ t - wrench)) ** 2))
        scale = float(np.sum((weights * wrench) ** 2))
        assert misfit(tension) <= misfit(reference) + 1e-7 * scale
        if misfit(reference) < 1e-12 * scale:
            exact += 1
            assert misfit(tension) < 1e-9 * scale
    # both kinds drawn
    assert 0 < exact < (300 if kernel == 'compiled' else 30)


def test_an_infeasible_wrench_names_the_robots_cable_not_the_column_of_the_cables_left(light_tall_robot_files):
    """With cable 1 broken the columns of S_R are cables 2, 3, 4: at this pose cable 3 holds
    1.39 N statically, under a floor of 2 N, and the error names cable 3 (its column is
    the second)."""
    robot = load_robot(light_tall_robot_files[0])
    attached = robot.cable_mask([0])
    still = np.zeros(3)
    with pytest.raises(InfeasibleTensionError, match=r'cable 3 cannot be brought to 2\.0 N'):
        inverse_dynamics(robot, BoundedMinimumNorm(2.0, robot.tension_max_n), np.array([0.467, 0.468, 2.49]),
                         still, still, attached=attached)
