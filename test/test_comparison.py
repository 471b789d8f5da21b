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
"""Figure 8's comparison paths: lengths against independent references, joins, ordering."""

import math

from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.geometry import ArcPolicy
from ellipath_ros.paper.comparison import (
    figure8_paths, half_ellipse_length, lame_path, lame_quarter_length, lame_quarter_points,
    symmetric_ellipse_path)
import numpy as np
import pytest

PAPER_L, PAPER_H = 0.150, 0.025


def trapezoid_quarter_ellipse(p, q, count=4096):
    """Quarter perimeter by the periodic trapezoid rule (exponentially accurate)."""
    t = np.linspace(0.0, 2.0 * math.pi, count, endpoint=False)
    return 0.25 * 2.0 * math.pi * float(np.mean(np.hypot(p * np.sin(t), q * np.cos(t))))


def polyline_length(points):
    """Sum of the chords of a polyline, shape (N, 2)."""
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def richardson_quarter(d, e, m, count=20001):
    """Quarter Lamé length from two polylines, extrapolated (chord error ~ 1/N**2)."""
    coarse = polyline_length(lame_quarter_points(d, e, m, count))
    fine = polyline_length(lame_quarter_points(d, e, m, 2 * count - 1))
    return fine + (fine - coarse) / 3.0


@pytest.mark.parametrize('d, e', [(0.15, 0.025), (0.05, 0.025), (0.02, 0.02), (0.01, 0.3)])
def test_lame_quarter_with_m_2_is_a_quarter_ellipse(d, e):
    reference = trapezoid_quarter_ellipse(d, e)
    assert lame_quarter_length(d, e, 2.0) == pytest.approx(reference, rel=1e-13)
    assert 0.5 * half_ellipse_length(d, e) == pytest.approx(reference, rel=1e-13)


@pytest.mark.parametrize('m', [2.5, 3.0, 4.0, 6.0])
@pytest.mark.parametrize('d', [0.05, 0.15])
def test_lame_quarter_length_matches_a_dense_polyline(d, m):
    assert lame_quarter_length(d, 0.025, m) == pytest.approx(
        richardson_quarter(d, 0.025, m), rel=1e-9)


def test_lame_quarter_length_grows_with_m_towards_the_square_corner():
    lengths = [lame_quarter_length(0.05, 0.025, m) for m in (2.0, 3.0, 4.0, 8.0, 100.0)]
    assert np.all(np.diff(lengths) > 0.0)
    assert lengths[-1] < 0.05 + 0.025
    assert lengths[-1] == pytest.approx(0.05 + 0.025, rel=0.01)


def test_lame_quarter_points_satisfy_the_curve_equation():
    points = lame_quarter_points(0.05, 0.025, 4.0, 101)
    np.testing.assert_allclose(np.abs(points[:, 0] / 0.05) ** 4
                               + np.abs(points[:, 1] / 0.025) ** 4, 1.0, rtol=1e-12)
    np.testing.assert_array_equal(points[0], [0.05, 0.0])
    np.testing.assert_array_equal(points[-1], [0.0, 0.025])


@pytest.mark.parametrize('h', [PAPER_H, -PAPER_H, 0.0, 0.07])
def test_every_path_joins_the_tangent_points_vertically(h):
    t1, t2 = np.array([-PAPER_L, -h]), np.array([PAPER_L, h])
    for path in figure8_paths(PAPER_L, h, ArcPolicy('apex_clearance')):
        np.testing.assert_allclose(path.points[0], t1, atol=1e-15)
        np.testing.assert_allclose(path.points[-1], t2, atol=1e-15)
        first, last = path.points[1] - path.points[0], path.points[-1] - path.points[-2]
        # Leaves T1 upwards and reaches T2 downwards, (nearly) vertically.
        assert first[1] > 0.0 and abs(first[0]) < 0.05 * first[1]
        assert last[1] < 0.0 and abs(last[0]) < 0.05 * -last[1]


@pytest.mark.parametrize('h', [PAPER_H, -PAPER_H, 0.0])
def test_lengths_and_apex_agree_with_the_samples(h):
    for path in figure8_paths(PAPER_L, h, ArcPolicy('apex_clearance'), samples=4001):
        assert path.length == pytest.approx(polyline_length(path.points), rel=1e-6)
        assert path.apex_height == pytest.approx(
            path.points[:, 1].max() + abs(h), abs=1e-8)


def test_paper_example_lengths_and_ordering():
    proposed, symmetric, narrow, wide = figure8_paths(PAPER_L, PAPER_H)
    assert [path.name for path in (proposed, symmetric, narrow, wide)] == [
        'proposed', 'symmetric_ellipse', 'lame_d0.05', 'lame_d0.15']
    assert symmetric.length == pytest.approx(
        2.0 * trapezoid_quarter_ellipse(PAPER_L, 0.025) + 2.0 * PAPER_H, rel=1e-13)
    assert narrow.length == pytest.approx(
        2.0 * richardson_quarter(0.05, 0.025, 4.0) + 0.2 + 0.05, rel=1e-9)
    assert wide.length == pytest.approx(
        2.0 * richardson_quarter(0.15, 0.025, 4.0) + 0.05, rel=1e-9)
    # The paper's claim on its example: the proposed arc is the shortest and lowest ...
    for other in (symmetric, narrow, wide):
        assert proposed.length < other.length
        assert proposed.apex_height < other.apex_height
    # ... and shorter than any path that rises vertically to the higher tangent point.
    assert proposed.length < 2.0 * PAPER_L + 2.0 * PAPER_H
    assert round(proposed.apex_height, 5) == 0.06852


def test_symmetric_ellipse_is_the_lame_path_with_m_2_and_d_l():
    symmetric = symmetric_ellipse_path(PAPER_L, PAPER_H, rise=0.03)
    lame = lame_path(PAPER_L, PAPER_H, PAPER_L, 0.03, m=2.0)
    assert symmetric.length == pytest.approx(lame.length, rel=1e-13)


def test_paper_rule_is_not_shortest_for_equal_heights():
    # The limitation reported in docs/paper_reproduction.md: at h = 0 the paper's
    # rule gives the semicircle, longer than the flat Lamé path.
    proposed, _, _, wide = figure8_paths(PAPER_L, 0.0)
    assert proposed.length == pytest.approx(math.pi * PAPER_L, rel=1e-12)
    assert proposed.length > wide.length


@pytest.mark.parametrize('call', [
    lambda: lame_path(PAPER_L, PAPER_H, 0.2),
    lambda: lame_path(PAPER_L, PAPER_H, 0.05, m=1.5),
    lambda: lame_quarter_length(0.05, 0.0),
    lambda: lame_quarter_points(0.05, 0.025, samples=1),
    lambda: symmetric_ellipse_path(PAPER_L, math.nan),
    lambda: symmetric_ellipse_path(0.0, PAPER_H),
])
def test_invalid_inputs_are_rejected(call):
    with pytest.raises(InvalidInputError):
        call()
