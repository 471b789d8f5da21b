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
"""The path's compiled kernels: each against its plain-Python form or an independent formula."""

import math

from ellipath_ros.core import geometry
from ellipath_ros.core.geometry import EllipticArc, plan_path
import numpy as np
import pytest


def random_ellipses(count, seed):
    """Yield (l, h, k) over thin, fat, level and steep tangent ellipses."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        yield (rng.uniform(0.005, 0.5), rng.uniform(-1.0, 1.0) * rng.choice([1e-3, 0.05, 1.0]),
               rng.uniform(0.002, 0.6) * rng.choice([0.05, 1.0]))


def ellipse_speed(l_, h, k, t):
    """Return |dP/dt| of P(t) = cos t (l, h) + sin t (0, k), NumPy on arrays."""
    return np.hypot(l_ * np.sin(t), k * np.cos(t) - h * np.sin(t))


@pytest.mark.parametrize('join', ['g2', 'paper'])
def test_path_rows_kernel_equals_its_python_form(join):
    path = plan_path((0.0, 0.0, -0.8), (0.3, 0.1, -0.75), 0.03, 0.02, join=join)
    rng = np.random.default_rng(3)
    # Unsorted, and beyond both ends (clipped), so that the panel search restarts.
    s = np.concatenate((np.linspace(-0.01, path.length + 0.01, 301),
                        rng.uniform(0.0, path.length, 200)))
    compiled, plain = np.empty((4, 3, s.size)), np.empty((4, 3, s.size))
    geometry._path_rows(s, path._frame, *path.bend._table, compiled)
    geometry._path_rows.py_func(s, path._frame, *path.bend._table, plain)
    np.testing.assert_allclose(compiled, plain, rtol=1e-12, atol=1e-12)
    assert np.abs(compiled[0] - path.rows_at_lengths(s)[0]).max() == 0.0


def test_panel_search_from_any_guess_is_the_bisection():
    panel_s = np.cumsum(np.random.default_rng(5).uniform(0.0, 1.0, 40))
    panel_s -= panel_s[0]
    rng = np.random.default_rng(6)
    for s in np.concatenate((rng.uniform(0.0, panel_s[-1], 300), panel_s)):
        expected = min(int(np.searchsorted(panel_s, s, side='right')) - 1, panel_s.size - 2)
        for guess in (0, expected - 1, expected, expected + 1, panel_s.size):
            assert geometry._panel_of(panel_s, s, guess) == expected


def test_ellipse_slowest_sample_is_the_whole_grids():
    t = geometry._dense_grid()
    for l_, h, k in random_ellipses(200, 11):
        found = geometry._ellipse_slowest((l_, h, k, 0.0, 0.0), t)
        assert found == pytest.approx(float(ellipse_speed(l_, h, k, t).min()), rel=1e-14)


def test_speed_check_decides_as_the_whole_grid():
    t = geometry._dense_grid()
    rng = np.random.default_rng(12)
    for l_, h, k in random_ellipses(150, 13):
        ellipse = EllipticArc(l_, h, k)
        spans = rng.uniform(0.05, geometry._BLEND_MAX_SPAN, 2)
        bend = geometry.BlendedArc(ellipse, *spans)
        slowest = float(bend.speed(t).min())
        # Thresholds on either side of the bent curve's slowest sample (as the kernel takes
        # them: at most the ellipse's slowest): the bound of the transitions' slope settles
        # the low ones, the grid the others.
        ellipse_slowest = float(ellipse_speed(l_, h, k, t).min())
        for share in (0.2, 0.5, 1.0 - 1e-9, 1.0 + 1e-9):
            least = min(share * slowest, ellipse_slowest)
            assert geometry._keeps_speed(bend._bend, ellipse.b, least, t) == (slowest >= least)


def test_slope_bound_bounds_the_shape():
    u = np.linspace(0.0, 1.0, 100001)
    slopes = np.array([geometry._blend_shape(value)[1] for value in u])
    assert np.abs(slopes).max() <= geometry._BLEND_SLOPE_BOUND


def test_transition_distance_is_the_largest_over_all_samples():
    u, shape, order = geometry._distance_grid()
    for l_, h, k in random_ellipses(60, 17):
        for span in (0.1, 0.6, 1.2):
            for at_t1 in (True, False):
                t = math.pi - span * u if at_t1 else span * u
                offset = l_ * span * span * shape
                bent_x = l_ * np.cos(t) + (-offset if at_t1 else offset)
                bent_y = h * np.cos(t) + k * np.sin(t)
                foot = t.copy()
                for _ in range(geometry._BLEND_FOOT_STEPS):
                    x, y = l_ * np.cos(foot), h * np.cos(foot) + k * np.sin(foot)
                    slope_x, slope_y = -l_ * np.sin(foot), k * np.cos(foot) - h * np.sin(foot)
                    gap_x, gap_y = x - bent_x, y - bent_y
                    rate = slope_x ** 2 + slope_y ** 2 - (gap_x * x + gap_y * y)
                    foot = np.clip(foot - (gap_x * slope_x + gap_y * slope_y) / rate, 0.0,
                                   math.pi)
                distance = np.hypot(l_ * np.cos(foot) - bent_x,
                                    h * np.cos(foot) + k * np.sin(foot) - bent_y)
                expected = float(np.minimum(distance, offset).max())
                found = geometry._transition_distance(
                    (l_, h, k, 0.0, 0.0), span, at_t1, u, shape, order,
                    geometry._BLEND_FOOT_STEPS)
                assert found == pytest.approx(expected, rel=1e-9, abs=1e-15)


def test_bend_kernels_equal_the_ellipse_and_its_offset():
    ellipse = EllipticArc(0.2, 0.04, 0.07)
    bend = geometry.BlendedArc(ellipse, 0.7, 0.5)
    t = np.linspace(math.pi, 0.0, 999)
    cos_t, sin_t = np.cos(t), np.sin(t)
    plain = np.array([0.2 * cos_t, 0.04 * cos_t + 0.07 * sin_t,
                      -0.2 * sin_t, 0.07 * cos_t - 0.04 * sin_t])
    (x, y), (x1, y1), (x2, y2), (x3, y3) = ellipse.components(t)
    np.testing.assert_allclose([x, y, x1, y1, x2, y2, x3, y3],
                               np.concatenate((plain, -plain)), rtol=0, atol=1e-15)
    delta = bend.offset(t)
    # Transitions by their definition: u = (pi - t) / span_1 near T1, t / span_2 near T2.
    near_1, near_2 = (math.pi - t) / 0.7 < 1.0, t / 0.5 < 1.0
    assert np.all(delta[:, ~(near_1 | near_2)] == 0.0)
    u = (math.pi - t[near_1]) / 0.7
    np.testing.assert_allclose(delta[0, near_1], -0.2 * 0.49 * u ** 2 * (1 - u) ** 4 / 2,
                               rtol=1e-9, atol=1e-15)
    (bx, by), (bx1, _), _, _ = bend.components(t)
    np.testing.assert_allclose(bx, x + delta[0], rtol=0, atol=1e-15)
    assert np.all(by == y)
    np.testing.assert_allclose(bend.speed(t), np.hypot(bx1, y1), rtol=1e-15)


def test_table_and_lookup_kernels_equal_their_python_forms():
    bend = plan_path((0.0, 0.0, -0.8), (0.3, 0.1, -0.75), 0.03, 0.02, join='g2').bend
    panel_t, panel_s, quintics = bend._table
    plain_s, plain_quintics = np.empty(panel_s.size), np.empty(quintics.shape)
    geometry._table_rows.py_func(bend._bend, panel_t, geometry.GAUSS_LEGENDRE_NODES,
                                 geometry.GAUSS_LEGENDRE_WEIGHTS, *geometry._panel_table(),
                                 plain_s, plain_quintics)
    np.testing.assert_allclose(panel_s, plain_s, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(quintics, plain_quintics, rtol=1e-11, atol=1e-13)
    t = np.random.default_rng(21).uniform(-0.1, math.pi + 0.1, 300)
    lengths = np.empty(t.size)
    geometry._s_from_t_rows.py_func(bend._bend, panel_t, panel_s, t,
                                    geometry.GAUSS_LEGENDRE_NODES,
                                    geometry.GAUSS_LEGENDRE_WEIGHTS, lengths)
    np.testing.assert_allclose(bend.s_from_t(t), lengths, rtol=1e-13, atol=1e-15)
    back = np.empty(t.size)
    geometry._t_from_s_rows.py_func(panel_t, panel_s, quintics, lengths, back)
    np.testing.assert_allclose(bend.t_from_s(lengths), back, rtol=1e-13, atol=1e-15)
    kappa, rate = np.empty(t.size), np.empty(t.size)
    geometry._curvature_rows.py_func(bend._bend, t, kappa, rate)
    np.testing.assert_allclose(bend.curvature_and_rate(t), (kappa, rate), rtol=1e-12,
                               atol=1e-12)


def test_curvature_grid_gives_the_curvature_and_the_speed_of_one_evaluation():
    bend = plan_path((0.0, 0.0, -0.8), (0.3, 0.1, -0.75), 0.03, 0.02, join='g2').bend
    t, kappa, rate, speed = bend.curvature_on_grid(1025)
    np.testing.assert_allclose(t, np.linspace(math.pi, 0.0, 1025), rtol=0, atol=0)
    # The grid's speed is the curve's |dQ/dt| from its components (an independent formula).
    x1, y1 = bend.components(t)[1]
    np.testing.assert_allclose(speed, np.hypot(x1, y1), rtol=1e-14)
    np.testing.assert_allclose((kappa, rate), bend.curvature_and_rate(t), rtol=1e-14,
                               atol=1e-12)
    plain = np.empty((3, t.size))
    geometry._grid_rows.py_func(bend._bend, geometry._trig_table(t), *plain)
    np.testing.assert_allclose(plain, (kappa, rate, speed), rtol=1e-13, atol=1e-12)


def test_shared_cosines_give_the_tables_of_the_curves_own_bit_for_bit():
    # The dense grid's and the panels' cosines and sines are computed once for every curve:
    # its grid and arc-length table equal those that evaluate them per curve.
    rng = np.random.default_rng(23)
    for l_, h, k in random_ellipses(20, 24):
        ellipse = EllipticArc(l_, h, k)
        for bend in (ellipse, geometry.BlendedArc(
                ellipse, *rng.uniform(0.05, geometry._BLEND_MAX_SPAN, 2))):
            t, kappa, rate, speed = bend.curvature_on_grid(geometry._DENSE_SAMPLES)
            own_kappa, own_rate, own_speed = (np.empty(t.size) for _ in range(3))
            geometry._curvature_rows(bend._bend, t.copy(), own_kappa, own_rate)
            geometry._speed_rows(bend._bend, t.copy(), own_speed)
            for shared, own in ((kappa, own_kappa), (rate, own_rate), (speed, own_speed)):
                assert np.array_equal(shared, own)
            panel_t, panel_s, quintics = bend._table
            # No shared grid: every bound and panel evaluated on its own.
            own_s, own_quintics = np.empty(panel_s.size), np.empty(quintics.shape)
            grid, panels = geometry._panel_table()
            geometry._table_rows(bend._bend, panel_t, geometry.GAUSS_LEGENDRE_NODES,
                                 geometry.GAUSS_LEGENDRE_WEIGHTS, grid[:, :0], panels[:0],
                                 own_s, own_quintics)
            assert np.array_equal(panel_s, own_s) and np.array_equal(quintics, own_quintics)


def libm(function, values):
    """Return ``function`` (math.cos, math.sin) of each of ``values``, shaped alike."""
    return np.array([function(value) for value in values.ravel()]).reshape(values.shape)


def test_panel_table_holds_the_quadratures_nodes():
    grid, panels = geometry._panel_table()
    assert np.array_equal(grid[0], geometry._panel_grid())
    assert np.array_equal(grid[1:], (libm(math.cos, grid[0]), libm(math.sin, grid[0])))
    edges = geometry._panel_grid()
    half = 0.5 * (edges[1:] - edges[:-1])
    nodes = (0.5 * (edges[1:] + edges[:-1])[:, None]
             + half[:, None] * geometry.GAUSS_LEGENDRE_NODES)
    assert np.array_equal(panels[:, 0], nodes)
    assert np.array_equal(panels[:, 1], libm(math.cos, nodes))
    assert np.array_equal(panels[:, 2], libm(math.sin, nodes))
    assert np.all(panels[:, 3] == np.abs(half)[:, None])


def test_ellipse_speed_alone_is_ellipse_sigmas_bit_for_bit():
    theta = np.random.default_rng(29).uniform(-7.0, 7.0, (64, 8))
    for l_, h, k in random_ellipses(10, 30):
        arc = EllipticArc(l_, h, k)
        assert np.array_equal(geometry.ellipse_speed(arc.a, arc.b, theta),
                              geometry.ellipse_sigma(arc.a, arc.b, theta)[0])
