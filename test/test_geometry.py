# Copyright 2026 The ellipath_ros authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.
"""The paper's path: reference values of its example, edge cases and invariants."""

import math

from ellipath_ros.core.errors import DegenerateGeometryError, InvalidInputError
from ellipath_ros.core.geometry import (
    arc_for_policy, ArcPolicy, blend_arc, conjugate_k_from_phi, EllipticArc, paper_phi,
    plan_path)
from ellipath_ros.paper.equations import paper_apex, paper_axes
import numpy as np
import pytest

PAPER_L, PAPER_H = 0.150, 0.025


def independent_length(arc, panels=4000):
    """Arc length by composite 5-point Gauss-Legendre in the paper's theta."""
    nodes, weights = np.polynomial.legendre.leggauss(5)
    edges = np.linspace(arc.theta_T2, arc.theta_T1, panels + 1)
    half = 0.5 * np.diff(edges)
    theta = (0.5 * (edges[1:] + edges[:-1]))[:, None] + half[:, None] * nodes
    speed = np.sqrt(arc.a ** 2 * np.sin(theta) ** 2 + arc.b ** 2 * np.cos(theta) ** 2)
    return float(np.sum(half[:, None] * weights * speed))


def local_coordinates(arc, points):
    """Rotate paper-frame points into the ellipse's principal frame (eq. 2a)."""
    c, s = math.cos(arc.phi), math.sin(arc.phi)
    return np.stack((points[:, 0] * c + points[:, 1] * s,
                     -points[:, 0] * s + points[:, 1] * c), axis=-1)


def test_paper_example_reproduces_printed_digits():
    arc = arc_for_policy(PAPER_L, PAPER_H, ArcPolicy('paper'))
    assert round(math.degrees(arc.phi), 9) == 10.0
    assert round(arc.a, 5) == 0.15219
    assert round(arc.b, 5) == 0.03511
    # Printed under swapped labels in the paper (erratum 1): -2.329 deg is T2.
    assert round(math.degrees(arc.theta_T2), 3) == -2.329
    assert round(math.degrees(arc.theta_T1), 3) == 177.671
    assert round(arc.length_approx, 5) == 0.32058
    assert np.array_equal(np.round(arc.apex, 5), [0.08617, 0.04352])
    # Erratum 2: the printed H* is y* + h, not |y*|.
    assert round(arc.apex_height, 5) == 0.06852


def test_paper_equations_agree_with_conjugate_form():
    phi = paper_phi(PAPER_L, PAPER_H)
    a, b = paper_axes(PAPER_L, PAPER_H, phi)
    arc = EllipticArc(PAPER_L, PAPER_H, conjugate_k_from_phi(PAPER_L, PAPER_H, phi))
    assert arc.a == pytest.approx(a, rel=1e-12)
    assert arc.b == pytest.approx(b, rel=1e-12)
    assert math.sin(arc.theta_T2) == pytest.approx(
        (-PAPER_L * math.sin(phi) + PAPER_H * math.cos(phi)) / b, rel=1e-12)
    np.testing.assert_allclose(paper_apex(a, b, phi), arc.apex, rtol=1e-12)


def test_exact_length_is_much_better_than_the_approximation():
    arc = arc_for_policy(PAPER_L, PAPER_H, ArcPolicy('paper'))
    reference = independent_length(arc)
    assert arc.length == pytest.approx(reference, rel=1e-9)
    # Erratum 4: eq. (27) is about 1 % low on the example.
    assert 0.005 < 1.0 - arc.length_approx / arc.length < 0.015


@pytest.mark.parametrize('k_over_l', [1e-3, 0.05, 0.3, 1.0, 3.0])
def test_exact_length_for_thin_and_fat_arcs(k_over_l):
    arc = EllipticArc(0.1, 0.02, 0.1 * k_over_l)
    assert arc.length == pytest.approx(independent_length(arc, panels=20000), rel=1e-9)


def test_equal_heights_give_the_semicircle_limit():
    arc = arc_for_policy(0.12, 0.0, ArcPolicy('paper'))
    assert arc.a == pytest.approx(0.12, rel=1e-12) and arc.b == pytest.approx(0.12, rel=1e-12)
    assert arc.length == pytest.approx(math.pi * 0.12, rel=1e-12)
    for tiny in (1e-12, -1e-12, 1e-9):
        near = arc_for_policy(0.12, tiny, ArcPolicy('paper'))
        assert near.length == pytest.approx(math.pi * 0.12, rel=1e-6)
        assert np.all(np.isfinite([near.a, near.b, near.phi, near.theta_T1]))


def test_place_lower_than_pick_mirrors_the_path():
    up = arc_for_policy(PAPER_L, PAPER_H, ArcPolicy('paper'))
    down = arc_for_policy(PAPER_L, -PAPER_H, ArcPolicy('paper'))
    assert down.phi == pytest.approx(-up.phi, abs=1e-15)
    assert (down.a, down.b) == pytest.approx((up.a, up.b), rel=1e-12)
    assert down.length == pytest.approx(up.length, rel=1e-12)
    assert down.apex_height == pytest.approx(up.apex_height, rel=1e-12)
    # Mirror about the vertical axis: the apex moves to the other side.
    assert down.apex[0] == pytest.approx(-up.apex[0], rel=1e-12)


@pytest.mark.parametrize('critical_deg', [10.0, 30.0, 45.0])
def test_critical_angle_on_or_just_below_a_whole_degree_takes_the_next_one(critical_deg):
    for offset in (0.0, 1e-9, 1e-4, 0.05):
        h = PAPER_L * math.tan(math.radians(critical_deg - offset))
        phi = paper_phi(PAPER_L, h)
        assert math.degrees(phi) == pytest.approx(critical_deg + 1.0)
        arc = arc_for_policy(PAPER_L, h, ArcPolicy('paper'))
        assert arc.b > 0.01 * arc.a


# The documented threshold (docs/paper_reproduction.md, erratum 3): the paper's ellipse is
# kept unless it rises less than a tenth of the half-width above the chord's midpoint.
DOCUMENTED_MIN_BULGE = 0.1


def test_small_critical_angle_keeps_the_papers_fat_ellipse():
    # Clearances 25 mm: T1 = (-0.1525, 0, -0.875), T2 = (0.1525, 0, -0.870), so
    # atan(h/l) = 0.94 deg and the paper's rule gives phi* = 1 deg (not 2 deg).
    path = plan_path((-0.1525, 0.0, -0.9), (0.1525, 0.0, -0.895))
    arc = path.arc
    assert math.degrees(math.atan2(arc.h, arc.l)) == pytest.approx(0.9392, abs=1e-4)
    assert math.degrees(arc.phi) == pytest.approx(1.0, abs=1e-12)
    a, b = paper_axes(arc.l, arc.h, math.radians(1.0))
    assert (arc.a, arc.b) == pytest.approx((a, b), rel=1e-12)
    assert round(arc.b * 1e3, 1) == 37.6
    assert round(arc.min_radius * 1e3, 1) == 9.3
    # Apex 40 mm above the lower tangent point, against 114 mm at phi = 2 deg.
    assert round(arc.apex_height * 1e3) == 40
    assert path.apex[2] - path.tangent_1[2] == pytest.approx(arc.apex_height, rel=1e-12)


@pytest.mark.parametrize('whole_deg', [1, 2, 5, 10, 30, 45, 60, 80, 88])
def test_paper_rule_is_the_ceiling_wherever_its_ellipse_is_sound(whole_deg):
    # Independent of the conjugate form: a, b from the paper's eqs. (15)-(20), and
    # k = a b / l (the ellipse's area is pi a b = pi l k).
    for margin_deg in (0.9, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.003, 1e-3, 1e-4):
        critical = math.radians(whole_deg - margin_deg)
        h = PAPER_L * math.tan(critical)
        a, b = paper_axes(PAPER_L, h, math.radians(whole_deg))
        sound = a * b / PAPER_L >= DOCUMENTED_MIN_BULGE * PAPER_L
        expected = whole_deg if sound else whole_deg + 1
        assert math.degrees(paper_phi(PAPER_L, h)) == pytest.approx(expected, abs=1e-9), \
            (whole_deg, margin_deg)
    # At small angles the paper's result is kept well inside the old fixed 0.1 deg margin.
    if whole_deg <= 2:
        assert math.degrees(paper_phi(PAPER_L, PAPER_L * math.tan(
            math.radians(whole_deg - 0.05)))) == pytest.approx(whole_deg)


def test_needle_at_the_paper_angle_is_regularised_to_a_sound_arc():
    h = PAPER_L * math.tan(math.radians(1.0 - 1e-3))
    a, b = paper_axes(PAPER_L, h, math.radians(1.0))
    assert b / a < 0.05
    arc = arc_for_policy(PAPER_L, h, ArcPolicy('paper'))
    assert math.degrees(arc.phi) == pytest.approx(2.0)
    assert arc.k >= DOCUMENTED_MIN_BULGE * PAPER_L and arc.b / arc.a > 0.5


def test_well_posed_critical_angle_keeps_the_paper_ceiling():
    h = PAPER_L * math.tan(math.radians(29.8))
    assert math.degrees(paper_phi(PAPER_L, h)) == pytest.approx(30.0)


def test_steep_moves_are_rejected_by_the_paper_rule_with_a_reason():
    with pytest.raises(DegenerateGeometryError, match='apex_clearance'):
        arc_for_policy(0.001, 0.2, ArcPolicy('paper'))
    arc = arc_for_policy(0.001, 0.2, ArcPolicy('apex_clearance', apex_clearance=0.02))
    assert arc.apex_height - 2 * 0.2 == pytest.approx(0.02, rel=1e-12)


@pytest.mark.parametrize('h', [-0.05, 0.0, 0.01, 0.2])
def test_apex_clearance_policy_puts_the_apex_where_asked(h):
    arc = arc_for_policy(0.15, h, ArcPolicy('apex_clearance', apex_clearance=0.03))
    assert arc.apex[1] - abs(h) == pytest.approx(0.03, rel=1e-12)


@pytest.mark.parametrize('h', [-0.04, 0.0, 0.025])
def test_min_radius_policy_is_the_shortest_arc_with_that_radius(h):
    arc = arc_for_policy(0.15, h, ArcPolicy('min_radius', min_radius=0.03))
    assert arc.min_radius == pytest.approx(0.03, rel=1e-9)
    sampled = arc.radius_of_curvature(np.linspace(arc.theta_T2, arc.theta_T1, 20001))
    assert sampled.min() >= 0.03 * (1 - 1e-9)
    thinner = EllipticArc(0.15, h, arc.k * (1 - 1e-6))
    assert thinner.min_radius < 0.03 and thinner.length < arc.length


def test_min_radius_beyond_what_any_ellipse_reaches_is_an_error():
    with pytest.raises(DegenerateGeometryError, match='min_radius: expected at most'):
        arc_for_policy(0.15, 0.0, ArcPolicy('min_radius', min_radius=0.2))


def test_points_lie_on_the_ellipse_with_vertical_tangents_at_the_ends():
    for h in (-0.03, 0.0, 0.025, 0.1):
        arc = arc_for_policy(0.15, h, ArcPolicy('paper'))
        theta = np.linspace(arc.theta_T2, arc.theta_T1, 101)
        local = local_coordinates(arc, arc.point(arc.t_from_theta(theta)))
        np.testing.assert_allclose((local[:, 0] / arc.a) ** 2 + (local[:, 1] / arc.b) ** 2, 1.0,
                                   atol=1e-12)
        np.testing.assert_allclose(arc.point([math.pi, 0.0]), [[-0.15, -h], [0.15, h]],
                                   atol=1e-15)
        assert np.abs(arc.derivative([math.pi, 0.0])[:, 0]).max() < 1e-12


def test_length_grows_with_phi_above_the_critical_angle():
    start = math.ceil(math.degrees(math.atan2(PAPER_H, PAPER_L)))
    lengths = []
    for phi_deg in range(start, 61):
        a, b = paper_axes(PAPER_L, PAPER_H, math.radians(phi_deg))
        lengths.append(EllipticArc(PAPER_L, PAPER_H, conjugate_k_from_phi(
            PAPER_L, PAPER_H, math.radians(phi_deg))).length)
    assert np.all(np.diff(lengths) > 0)


def test_radius_of_curvature_matches_the_composite_path_curvature():
    path = plan_path([0.0, 0.0, -0.8], [0.3, 0.0, -0.75])
    arc = path.arc
    s_arc = np.linspace(0.0, arc.length, 51)[1:-1]  # the joins belong to the lines
    samples = path.at_lengths(path.segment_ends[1] + s_arc)
    theta = arc.t_from_s(s_arc) + arc.theta_T2
    np.testing.assert_allclose(np.linalg.norm(samples.curvature, axis=1),
                               1.0 / arc.radius_of_curvature(theta), rtol=1e-9)
    assert arc.end_radius == pytest.approx(arc.radius_of_curvature(arc.theta_T1), rel=1e-12)


@pytest.mark.parametrize('place', [[0.3, 0.0, -0.75], [-0.2, 0.1, -0.9], [0.05, -0.25, -0.8]])
def test_composite_path_in_any_azimuth(place):
    pick = np.array([0.0, 0.05, -0.8])
    path = plan_path(pick, place, 0.02, 0.04)
    ends = path.at_lengths(path.segment_ends)
    np.testing.assert_allclose(ends.position, [pick, pick + [0, 0, 0.02],
                                               np.add(place, [0, 0, 0.04]), place], atol=1e-12)
    # Tangent continuous (vertical) at T1 and T2, from both sides.
    joins = path.segment_ends[1:3]
    for side in (-1e-9, 1e-9):
        tangent = path.at_lengths(joins + side).tangent
        np.testing.assert_allclose(np.abs(tangent), [[0, 0, 1], [0, 0, 1]], atol=1e-6)
    s = np.linspace(0.0, path.length, 20001)
    samples = path.at_lengths(s)
    # All points in the vertical plane through pick and place.
    normal = np.cross(path.direction, [0.0, 0.0, 1.0])
    assert np.abs((samples.position - pick) @ normal).max() < 1e-12
    # Sampling is by arc length: unit speed and consistent derivatives.
    step = np.linalg.norm(np.diff(samples.position, axis=0), axis=1)
    assert step == pytest.approx(np.full_like(step, s[1]), rel=1e-5)
    np.testing.assert_allclose(np.linalg.norm(samples.tangent, axis=1), 1.0, atol=1e-12)


def test_third_derivative_matches_finite_differences_on_the_arc():
    path = plan_path([0.0, 0.0, -0.8], [0.3, 0.0, -0.75])
    s = path.segment_ends[1] + np.linspace(0.01, path.arc.length - 0.01, 2001)
    step = 1e-6
    ahead, behind = path.at_lengths(s + step), path.at_lengths(s - step)
    here = path.at_lengths(s)
    np.testing.assert_allclose((ahead.curvature - behind.curvature) / (2 * step),
                               here.curvature_rate, atol=1e-4 * np.abs(here.curvature_rate).max())


def test_pure_vertical_moves_have_no_arc():
    up = plan_path([0.1, 0.1, -0.9], [0.1, 0.1, -0.8])
    assert up.arc is None and up.length == pytest.approx(0.1)
    np.testing.assert_allclose(up.at_lengths([0.05]).position, [[0.1, 0.1, -0.85]])
    down = plan_path([0.1, 0.1, -0.8], [0.1, 0.1, -0.9])
    samples = down.at_lengths([0.0, 0.1])
    np.testing.assert_allclose(samples.position, [[0.1, 0.1, -0.8], [0.1, 0.1, -0.9]])
    np.testing.assert_allclose(samples.tangent, [[0, 0, -1], [0, 0, -1]])


def test_bad_inputs_are_rejected_with_the_value():
    with pytest.raises(DegenerateGeometryError, match='pick and place'):
        plan_path([0.1, 0.0, -0.8], [0.1, 0.0, -0.8])
    with pytest.raises(InvalidInputError, match='pick: expected finite'):
        plan_path([math.nan, 0.0, -0.8], [0.1, 0.0, -0.8])
    with pytest.raises(InvalidInputError, match=r'place: expected 3 coordinates'):
        plan_path([0.0, 0.0, -0.8], [0.1, 0.0])
    with pytest.raises(InvalidInputError, match=r'pick_clearance: expected a value in \[0, 1\]'):
        plan_path([0.0, 0.0, -0.8], [0.1, 0.0, -0.8], pick_clearance=-0.01)
    with pytest.raises(InvalidInputError, match='arc_policy: expected one of'):
        ArcPolicy('lame')
    with pytest.raises(InvalidInputError, match='apex_clearance'):
        ArcPolicy('apex_clearance', apex_clearance=0.0)


def test_tiny_horizontal_offsets_go_straight_to_the_place():
    path = plan_path([0.0, 0.0, -0.8], [5e-4, 0.0, -0.7])
    assert path.arc is None
    ends = path.at_lengths([0.0, path.length])
    np.testing.assert_allclose(ends.position, [[0.0, 0.0, -0.8], [5e-4, 0.0, -0.7]],
                               atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(ends.tangent, axis=1), 1.0)


def test_needle_thin_arcs_are_rejected_with_a_remedy():
    with pytest.raises(DegenerateGeometryError, match='smallest radius of curvature'):
        plan_path([0.0, 0.0, -0.85], [0.0011, 0.0, -0.55],
                  policy=ArcPolicy('apex_clearance', apex_clearance=0.025))


def test_coordinates_beyond_any_workspace_are_rejected():
    with pytest.raises(InvalidInputError, match=r'pick: expected coordinates within \+-10 m'):
        plan_path([1e308, 0.0, -0.8], [0.1, 0.0, -0.8])


def test_t_from_s_inverts_the_arc_length_on_thin_and_bent_arcs():
    """The table's interpolation against the arc length by quadrature (s_from_t)."""
    thin = EllipticArc(0.15, 0.02, 0.004)  # smallest radius about 0.1 mm
    bent = blend_arc(EllipticArc(0.15, 0.05, 0.04))
    for arc in (thin, bent):
        s = np.linspace(0.0, arc.length, 4001)
        t = arc.t_from_s(s)
        assert np.all(np.diff(t) < 0.0)
        assert np.abs(arc.s_from_t(t) - s).max() < 1e-9


def test_sigma_is_the_speed_in_theta_and_its_derivatives():
    arc = EllipticArc(0.15, 0.03, 0.05)
    theta = np.linspace(-3.0, 3.0, 13)
    sigma, sigma_1, sigma_2 = arc.sigma(theta)
    np.testing.assert_allclose(sigma, arc.speed(arc.t_from_theta(theta)), rtol=1e-14)
    step = 1e-4
    ahead, behind = arc.sigma(theta + step)[0], arc.sigma(theta - step)[0]
    np.testing.assert_allclose(sigma_1, (ahead - behind) / (2 * step), atol=1e-9)
    np.testing.assert_allclose(sigma_2, (ahead - 2 * sigma + behind) / step ** 2, atol=1e-6)
    np.testing.assert_allclose(arc.radius_of_curvature(theta), sigma ** 3 / (arc.a * arc.b),
                               rtol=1e-12)
