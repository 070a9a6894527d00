"""Static equilibrium, SEW cross-sections and safe points against geometry and an LP."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from cdpr_control.point_mass.kinematics import structure_matrix
from cdpr_control.point_mass.statics import in_static_equilibrium, static_tensions
from cdpr_control.point_mass.workspace import (contains, convex_hull, polygon_centroid, safe_point,
                                    sew_cross_section)
from conftest import cable_masks, random_positions

A, B = 1.688, 1.930      # paper frame (DESIGN §6)


def _holdable(robot, p, attached):
    """Independent test: non-negative tensions of the attached cables balance gravity (LP)."""
    s, _ = structure_matrix(robot, p)
    s = s[:, attached]
    result = linprog(np.zeros(s.shape[1]), A_eq=s, b_eq=-robot.weight_wrench_n,
                     bounds=[(0, None)] * s.shape[1], method='highs')
    assert result.status in (0, 2)
    return result.status == 0


def _distance_to_border(polygon, xy):
    distances = []
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0)):
        t = np.clip((xy - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        distances.append(np.linalg.norm(a + t * (b - a) - xy))
    return min(distances)


def _signed_area(polygon):
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def test_static_tensions_balance_gravity(robot, rng):
    positions, checked = 10, 0
    for label, attached in cable_masks(robot):
        for p in random_positions(robot, rng, positions):
            checked += 1
            tensions = static_tensions(robot, p, attached)
            s, _ = structure_matrix(robot, p)
            np.testing.assert_allclose(s @ tensions, -robot.weight_wrench_n, atol=1e-9, err_msg=label)
            assert np.all(tensions[~attached] == 0.0)
            np.testing.assert_allclose(tensions[attached], np.linalg.pinv(s[:, attached]) @ -robot.weight_wrench_n,
                                       atol=1e-9)
    # every cable, then each one broken
    assert checked == positions * (robot.cable_count + 1)


def test_static_tensions_symmetric_at_paper_frame_centre(paper_robot):
    p = np.array([A / 2, B / 2, 1.25])
    tensions = static_tensions(paper_robot, p, np.ones(4, dtype=bool))
    # four equal cables share the weight: 4 τ sin(elevation) = m g
    d = np.linalg.norm(paper_robot.exit_points_m[0] - p)
    expected = paper_robot.mass_kg * 9.81 / (4 * (paper_robot.exit_points_m[0, 2] - p[2]) / d)
    np.testing.assert_allclose(tensions, expected, rtol=1e-12)


def test_in_static_equilibrium_at_frame_centre(robot):
    centre = 0.5 * (robot.workspace_min_m + robot.workspace_max_m)
    assert in_static_equilibrium(robot, centre, np.ones(robot.cable_count, dtype=bool))


def test_not_in_equilibrium_outside_residual_workspace(paper_robot):
    attached = paper_robot.cable_mask([3])     # cable 4 broken: triangle A1 A2 A3 remains
    near_a4 = np.array([1.5, 0.2, 1.2])
    assert not in_static_equilibrium(paper_robot, near_a4, attached)
    assert np.min(static_tensions(paper_robot, near_a4, attached)) < 0.0
    assert in_static_equilibrium(paper_robot, np.array([0.3, 1.6, 1.2]), attached)
    # outside the frame altogether, even with every cable
    assert not in_static_equilibrium(paper_robot, np.array([-0.2, 0.9, 1.0]), np.ones(4, dtype=bool))


def _heights(robot):
    heights = [robot.workspace_min_m[2] + 0.3, robot.workspace_max_m[2] - 0.1]
    z = np.sort(robot.exit_points_m[:, 2])
    if z[0] < z[-1]:
        heights.append(0.5 * (z[1] + z[2]))    # between exit-point heights: some are below
    return heights


def test_equilibrium_agrees_with_cross_section_on_a_grid(robot):
    low, high = robot.workspace_min_m - 0.4, robot.workspace_max_m + 0.4
    xs = np.linspace(low[0], high[0], 11) + 0.0123
    ys = np.linspace(low[1], high[1], 11) + 0.0071
    inside_count = outside_count = 0
    for label, attached in cable_masks(robot):
        for height in _heights(robot):
            polygon = sew_cross_section(robot, attached, height)
            assert _signed_area(polygon) > 0.0, 'border must be counter-clockwise'
            for i, x in enumerate(xs):
                for j, y in enumerate(ys):
                    xy = np.array([x, y])
                    if _distance_to_border(polygon, xy) < 1e-3:
                        continue
                    p = np.array([x, y, height])
                    inside = contains(polygon, xy)
                    assert in_static_equilibrium(robot, p, attached) == inside, f'{label}, p = {p}'
                    if (i + j) % 3 == 0:        # the LP on a third of the points, for speed
                        assert _holdable(robot, p, attached) == inside, f'{label}, p = {p}'
                    inside_count += inside
                    outside_count += not inside
    assert inside_count > 100 and outside_count > 100


def test_all_paper_cables_give_the_frame_rectangle(paper_robot):
    polygon = sew_cross_section(paper_robot, np.ones(4, dtype=bool), 1.0)
    assert sorted(map(tuple, np.round(polygon, 12))) == [(0.0, 0.0), (0.0, B), (A, 0.0), (A, B)]
    assert _signed_area(polygon) == pytest.approx(A * B)


@pytest.mark.parametrize('height', [0.3, 1.22, 1.38, 2.0])
def test_paper_safe_point_after_cable_4_breaks(paper_robot, height):
    sp = safe_point(paper_robot, paper_robot.cable_mask([3]), height)
    np.testing.assert_allclose(sp, [0.5627, 1.2867, height], atol=1e-4)
    # the barycentre of the triangle of the remaining exit points' projections
    np.testing.assert_allclose(sp[:2], paper_robot.exit_points_m[:3, :2].mean(axis=0), atol=1e-12)


@pytest.mark.parametrize('broken', range(4))
def test_paper_safe_points_by_symmetry(paper_robot, broken):
    sp = safe_point(paper_robot, paper_robot.cable_mask([broken]), 1.2)
    remaining = np.delete(paper_robot.exit_points_m[:, :2], broken, axis=0)
    np.testing.assert_allclose(sp[:2], remaining.mean(axis=0), atol=1e-12)
    assert in_static_equilibrium(paper_robot, sp, paper_robot.cable_mask([broken]))
    assert np.all(static_tensions(paper_robot, sp, paper_robot.cable_mask([broken]))[
        paper_robot.cable_mask([broken])] > 0.0)


def test_eight_cable_safe_points_hold(robot):
    heights = (robot.workspace_min_m[2] + 0.3, 1.5, robot.workspace_max_m[2] - 0.1)
    checked = 0
    for label, attached in cable_masks(robot):
        for height in heights:
            checked += 1
            sp = safe_point(robot, attached, height)
            polygon = sew_cross_section(robot, attached, height)
            assert sp[2] == height
            assert contains(polygon, sp[:2]), label
            assert _distance_to_border(polygon, sp[:2]) > 0.1, label
            assert in_static_equilibrium(robot, sp, attached), label
            assert _holdable(robot, sp, attached), label
    # every cable, then each one broken
    assert checked == len(heights) * (robot.cable_count + 1)


def test_polygon_centroid_closed_forms():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    np.testing.assert_allclose(polygon_centroid(square), [0.5, 0.5], atol=1e-15)
    np.testing.assert_allclose(polygon_centroid(square[::-1]), [0.5, 0.5], atol=1e-15)
    np.testing.assert_allclose(polygon_centroid(square * 3.0 + [2.0, -1.0]), [3.5, 0.5], atol=1e-12)
    triangle = np.array([[0.0, 0.0], [4.0, 0.0], [1.0, 3.0]])
    np.testing.assert_allclose(polygon_centroid(triangle), triangle.mean(axis=0), atol=1e-15)
    np.testing.assert_allclose(polygon_centroid(triangle[::-1]), [5.0 / 3.0, 1.0], atol=1e-15)
    # L shape: 2x1 rectangle plus 1x1 square on top of its left half
    shape = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
    expected = (2 * np.array([1.0, 0.5]) + 1 * np.array([0.5, 1.5])) / 3
    np.testing.assert_allclose(polygon_centroid(shape), expected, atol=1e-15)
    with pytest.raises(ValueError):
        polygon_centroid(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))


def test_convex_hull_matches_scipy(rng):
    for _ in range(10):
        points = rng.normal(size=(30, 2))
        hull = convex_hull(points)
        expected = points[ConvexHull(points).vertices]
        assert len(hull) == len(expected)
        gaps = np.linalg.norm(hull[:, None, :] - expected[None, :, :], axis=2)
        assert np.all(gaps.min(axis=1) < 1e-9) and np.all(gaps.min(axis=0) < 1e-9)
        assert _signed_area(hull) > 0.0
        assert all(contains(hull, p) for p in points)


def test_contains_square():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert contains(square, [0.5, 0.5]) and contains(square, [1.0, 0.3])
    assert not contains(square, [1.01, 0.5]) and not contains(square, [-0.2, -0.2])
