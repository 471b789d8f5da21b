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

"""The timed motion's compiled sampling: states and norms, peaks between samples."""

import math

from ellipath_ros.core import motion as motion_module
from ellipath_ros.core import optimal_profile
from ellipath_ros.core.geometry import plan_path
from ellipath_ros.core.limits import CartesianLimits
from ellipath_ros.core.timing import time_motion
import numpy as np
import pytest


@pytest.fixture(scope='module', params=['g2', 'paper'])
def timed(request):
    """Return a time-optimal leg, fresh (not sampled yet)."""
    path = plan_path((0.1, 0.05, -0.8), (-0.2, 0.1, -0.75), 0.025, 0.02, join=request.param)
    return time_motion(path, CartesianLimits())


def test_state_rows_are_the_paths_rows_times_the_law(timed):
    t = np.linspace(0.0, timed.duration, 777)
    s, v, a, j = timed.path_state(t)
    states, norms = np.empty((4, t.size, 3)), np.empty((3, t.size))
    motion_module._state_rows(s, v, a, j, timed.path._frame, *timed.path.bend._table, states,
                              norms)
    # Independently: the path's rows (position, unit tangent, d2p/ds2, d3p/ds3) by the chain
    # rule, in NumPy.
    position, tangent, curvature, rate = (rows.T for rows in timed.path.rows_at_lengths(s))
    velocity = v[:, None] * tangent
    acceleration = a[:, None] * tangent + (v ** 2)[:, None] * curvature
    jerk = (j[:, None] * tangent + (3.0 * v * a)[:, None] * curvature
            + (v ** 3)[:, None] * rate)
    for found, expected in zip(states, (position, velocity, acceleration, jerk)):
        np.testing.assert_allclose(found, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(norms, np.linalg.norm([velocity, acceleration, jerk], axis=2),
                               rtol=1e-12, atol=1e-9)
    plain_states, plain_norms = np.empty_like(states), np.empty_like(norms)
    motion_module._state_rows.py_func(s, v, a, j, timed.path._frame, *timed.path.bend._table,
                                      plain_states, plain_norms)
    np.testing.assert_allclose(plain_states, states, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(plain_norms, norms, rtol=1e-13, atol=1e-12)


def test_refined_peaks_find_a_parabolas_vertex_between_samples():
    # Two pieces; in the first, a parabola whose vertex (value 5) lies between samples.
    t = np.array([0.0, 1.0, 2.0, 3.0, 3.0, 4.0])
    pieces = np.array([0, 0, 0, 0, 1, 1])
    values = 5.0 - (t - 1.4) ** 2
    # In the second piece a sample beside the bound is the largest: no vertex across it.
    values[4:] = (4.0, 4.5)
    norms = np.vstack((values, values, np.full(t.size, 2.0)))
    peaks = np.empty(3)
    motion_module._refined_peaks(t, pieces, norms, peaks)
    np.testing.assert_allclose(peaks, (5.0, 5.0, 2.0), rtol=1e-14)
    plain = np.empty(3)
    motion_module._refined_peaks.py_func(t, pieces, norms, plain)
    assert np.array_equal(plain, peaks)
    # Across a bound of the pieces the three samples are not one smooth function: no vertex.
    motion_module._refined_peaks(t, np.array([0, 0, 1, 1, 2, 2]), norms, peaks)
    assert peaks[0] == values.max()
    # Uneven gaps (a sample just off a bound beside a grid sample): no extrapolation from them.
    uneven = np.array([0.0, 1.0, 1.01])
    steep = np.vstack([1.0 - (uneven - 1.3) ** 2] * 3)
    motion_module._refined_peaks(uneven, np.zeros(3, dtype=np.int64), steep, peaks)
    assert np.all(peaks == steep[:, 2])


def peaks_with_every_vertex(t, pieces, norms):
    """Return each row's largest value or vertex, every triple's vertex computed (NumPy)."""
    h_1, h_2 = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    found = []
    for values in norms:
        d_1 = (values[1:-1] - values[:-2]) / h_1
        d_2 = (values[2:] - values[1:-1]) / h_2
        curvature = 2.0 * (d_2 - d_1) / (h_1 + h_2)
        slope = (d_1 * h_2 + d_2 * h_1) / (h_1 + h_2)
        usable = ((pieces[:-2] == pieces[1:-1]) & (pieces[2:] == pieces[1:-1])
                  & (np.minimum(h_1, h_2) >= motion_module._EVEN_SPACING
                     * np.maximum(h_1, h_2)) & (h_1 > 0.0) & (curvature < 0.0)
                  & (h_1 * curvature <= slope) & (slope <= -h_2 * curvature))
        vertices = values[1:-1] - slope ** 2 / (2.0 * curvature)
        found.append(max(values.max(), vertices[usable].max(initial=-np.inf)))
    return found


def test_refined_peaks_skip_only_triples_that_cannot_raise_the_peak():
    """The screen before the divisions keeps every vertex that counts, bit for bit."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        count = int(rng.integers(3, 400))
        # Even steps with some narrow and wide gaps, pieces of random lengths, and norms with
        # many parabolic hills of nearly the same height, their tops between samples: the
        # peak is often a vertex above every sample (of another hill than the top sample's).
        t = np.cumsum(rng.choice([1.0, 1.0, 1.0, 0.3, 0.2, 4.5], count))
        pieces = np.cumsum(rng.random(count) < 0.05)
        tops = rng.uniform(t[0], t[-1], 20)
        hills = (1.0 + rng.uniform(0.0, 1e-3, 20)) - rng.uniform(1e-3, 1e-2) * (
            t[:, None] - tops) ** 2
        norms = np.abs(np.vstack([hills.max(axis=1), np.sin(rng.uniform(0.05, 1.5) * t),
                                  rng.uniform(0.0, 1.0, count)]))
        peaks = np.empty(3)
        motion_module._refined_peaks(t, pieces, norms, peaks)
        assert peaks.tolist() == peaks_with_every_vertex(t, pieces, norms)


def test_curvature_profile_samples_follow_its_pieces_not_its_duration():
    path = plan_path((0.0, 0.0, -0.8), (0.3, 0.0, -0.75), join='paper')
    limits = CartesianLimits()
    fast = time_motion(path, limits, profile='curvature')
    slow = time_motion(path, CartesianLimits(max_speed=0.05, max_accel=0.5, max_jerk=50.0),
                       profile='curvature')
    assert slow.duration > 10.0 * fast.duration
    fast_count, slow_count = (motion.sampled_norms()[0].size for motion in (fast, slow))
    # The same path's law has the same pieces (but its lines' Ruckig pieces may differ).
    assert abs(slow_count - fast_count) < 0.2 * fast_count
    # And its peaks match a check every 10 us of the slow motion.
    t = np.linspace(0.0, slow.duration, int(slow.duration / 1e-5) + 1)
    _, velocity, acceleration, jerk = slow.state_at(t)
    metrics = slow.metrics()
    for key, vectors in (('peak_speed', velocity), ('peak_accel', acceleration),
                         ('peak_jerk', jerk)):
        dense = float(np.linalg.norm(vectors, axis=1).max())
        assert dense * (1.0 - 1e-6) <= metrics[key] <= dense * (1.0 + 1e-4), key


def test_sampled_peaks_are_not_below_a_dense_check_of_the_motion(timed):
    # The reported peaks (0.1 ms samples, refined) against a 2 MHz check of the same motion.
    metrics = timed.metrics()
    t = np.linspace(0.0, timed.duration, int(timed.duration / 5e-7) + 1)
    _, velocity, acceleration, jerk = timed.state_at(t)
    for key, vectors in (('peak_speed', velocity), ('peak_accel', acceleration),
                         ('peak_jerk', jerk)):
        dense = float(np.linalg.norm(vectors, axis=1).max())
        assert metrics[key] >= dense * (1.0 - 1e-5), key
        assert metrics[key] <= dense * (1.0 + 1e-4), key


def test_times_at_lengths_invert_the_law(timed):
    law = timed.law
    # Lengths all along the path, the piece bounds' own among them, and both ends.
    lengths = np.concatenate((np.linspace(0.0, timed.path.length, 101), law.s0[::7]))
    times = np.empty(lengths.size)
    motion_module._times_at_lengths(law.times, law.s0, law.v0, law.a0, law.jerk, lengths, times)
    np.testing.assert_allclose(law.state(times)[0], lengths, rtol=0, atol=1e-12)
    # The first time each length is reached: just before it the law is still short of it.
    before = law.state(np.maximum(times - 1e-7, 0.0))[0]
    assert np.all((before < lengths) | (lengths <= 0.0))
    plain = np.empty(lengths.size)
    motion_module._times_at_lengths.py_func(law.times, law.s0, law.v0, law.a0, law.jerk,
                                            lengths, plain)
    np.testing.assert_allclose(plain, times, rtol=0, atol=1e-15)


@pytest.mark.parametrize('join', ['g2', 'paper'])
def test_arc_planner_tables_are_simpsons_lengths_and_numpys_interpolation(join):
    path = plan_path((0.1, 0.05, -0.8), (-0.2, 0.1, -0.75), 0.025, 0.02, join=join)
    limits = CartesianLimits()
    planner = optimal_profile._ArcPlanner(path, limits, None)
    intervals = planner.grid.size - 1
    kappa_t, kappa_s_t, sigma = path.bend.curvature_on_grid(2 * intervals + 1)[1:]
    # Independently, in NumPy: Simpson on pairs of steps (pi / (2 K + 1) wide, as the table
    # counts them), linear at each pair's middle, scaled to the arc's length.
    pairs = (sigma[:-2:2] + 4.0 * sigma[1:-1:2] + sigma[2::2]) * (np.pi / sigma.size)
    even = np.concatenate(([0.0], np.cumsum(pairs) / 3.0 * 2.0))
    lengths = np.interp(np.arange(sigma.size), np.arange(0, sigma.size, 2), even)
    lengths *= planner.length / lengths[-1]
    grid = np.linspace(0.0, planner.length, intervals + 1)
    kappa = np.maximum(np.interp(grid, lengths, kappa_t), 0.0)
    kappa_s = np.interp(grid, lengths, kappa_s_t)
    found, found_s = np.empty(grid.size), np.empty(grid.size)
    optimal_profile._uniform_curvature(sigma, kappa_t, kappa_s_t, grid, found, found_s)
    np.testing.assert_allclose(found, kappa, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(found_s, kappa_s, rtol=1e-13, atol=1e-10 * np.abs(kappa_s).max())
    plain, plain_s = np.empty(grid.size), np.empty(grid.size)
    optimal_profile._uniform_curvature.py_func(sigma, kappa_t, kappa_s_t, grid, plain, plain_s)
    assert np.array_equal(plain, found) and np.array_equal(plain_s, found_s)
    # The ceiling: speed limit, sqrt(a / kappa) and (j / hypot(kappa**2, kappa_s))**(1/3).
    accel = optimal_profile._CEILING_SHARE * limits.max_accel * optimal_profile._ACCEL_MARGIN
    jerk = optimal_profile._CEILING_SHARE * limits.max_jerk * optimal_profile._JERK_MARGIN
    with np.errstate(divide='ignore'):
        ceiling = np.minimum.reduce([
            np.full(grid.size, limits.max_speed * optimal_profile._SPEED_MARGIN),
            np.sqrt(accel / kappa), (jerk / np.hypot(kappa ** 2, kappa_s)) ** (1.0 / 3.0)])
    np.testing.assert_allclose(planner.ceiling, ceiling, rtol=1e-13)


def test_jerk_on_a_line_takes_the_cube_of_pow_bit_for_bit():
    # Where the curvature rate is zero the kernel cubes the speed by products instead of pow:
    # the jerk must stay pow's bit for bit, the signs of zero products included.
    rng = np.random.default_rng(41)
    count = 4000
    position, tangent, curvature, rate = rng.normal(size=(4, 3, count))
    rate[:, : count // 2] = rng.choice([0.0, -0.0], size=(3, count // 2))
    # Columns with a zero rate on one or two axes only still take pow.
    rate[0, count // 2: 3 * count // 4] = 0.0
    tangent[:, ::7] = 0.0
    curvature[:, ::5] = -0.0
    v, a, j = rng.normal(size=(3, count)) * rng.choice([1e-3, 1.0, 1e3], size=(3, count))
    v[::11], v[::13], a[::17] = 0.0, -0.0, -0.0
    states = np.empty((4, count, 3))
    motion_module._cartesian_rows(position, tangent, curvature, rate, v, a, j, states)
    expected = np.array([[
        j[row] * tangent[axis, row] + (3.0 * v[row] * a[row]) * curvature[axis, row]
        + math.pow(v[row], 3.0) * rate[axis, row] for axis in range(3)] for row in range(count)])
    assert np.array_equal(states[3], expected)
    assert np.array_equal(np.signbit(states[3]), np.signbit(expected))


def steps_by_arrays(times, sizes, marks, jerk, epsilon, duration):
    """Return the merged jerk steps by the NumPy formulas they were first written in."""
    if marks.size and times.size:
        apart = np.abs(times[:, None] - marks[None, :]).min(axis=1) > epsilon
        times, sizes = times[apart], sizes[apart]
    times = np.concatenate((times, marks))
    sizes = np.concatenate((sizes, np.linalg.norm(jerk[marks.size:] - jerk[:marks.size],
                                                  axis=1)))
    order = np.argsort(times, kind='stable')
    times, sizes = times[order], sizes[order]
    unique = np.concatenate(([True], np.diff(times) > 0.0))
    inside = unique & (times > 0.0) & (times < duration)
    return times[inside], sizes[inside]


def test_merged_jerk_steps_are_the_array_formulas_bit_for_bit():
    rng = np.random.default_rng(43)
    for count, mark_count in ((0, 0), (5, 0), (0, 3), (40, 4), (300, 2)):
        times = np.sort(rng.uniform(-0.1, 1.1, count))
        # Repeated times, times at a mark's distance and the ends.
        times[::9] = np.round(times[::9], 1)
        marks = rng.uniform(0.0, 1.0, mark_count)
        if count and mark_count:
            times[1] = marks[0] + 5e-10
        sizes = rng.uniform(0.0, 50.0, count)
        jerk = rng.normal(size=(2 * mark_count, 3)) * 100.0
        found = motion_module._merged_steps(times, sizes, marks, jerk, 1e-9, 1.0)
        expected = steps_by_arrays(times, sizes, marks, jerk, 1e-9, 1.0)
        assert all(np.array_equal(mine, theirs) for mine, theirs in zip(found, expected))


def test_sequence_sample_times_are_the_array_formula_bit_for_bit():
    rng = np.random.default_rng(17)
    for durations in ((0.12, 0.3, 0.09), (0.2,), (0.1, 1e-12, 0.25, 0.05)):
        # Pieces of random widths (one law shorter than the offsets off its ends: out of
        # order before the sort).
        laws = []
        for duration in durations:
            widths = rng.uniform(0.1, 1.0, rng.integers(1, 30))
            times = np.concatenate(([0.0], np.cumsum(widths / widths.sum() * duration)))
            zeros = np.zeros(times.size - 1)
            laws.append(motion_module._JerkPieces(times, zeros, zeros, zeros, zeros))
        sequence = motion_module._Sequence(tuple(laws))
        for count in (1, 4, 7):
            starts = sequence._starts
            epsilon = 1e-9 * float(starts[-1])
            expected = np.sort(np.concatenate([start + np.clip(
                motion_module._piece_sample_times(law.times, count), epsilon,
                law.duration - epsilon) for start, law in zip(starts, laws)] + [starts]))
            found = sequence.sample_times(count)
            assert found.dtype == expected.dtype and np.array_equal(found, expected)


@pytest.mark.parametrize('factor', [1.0, 1.37])
def test_jerk_steps_of_a_time_optimal_leg_are_the_array_formulas_bit_for_bit(timed, factor):
    motion = timed.scaled(factor)
    law = motion.law
    # Independently: the law's steps and the jerk vectors beside the path's marks by the
    # NumPy formulas and state_at, merged as the kernel merges them.
    epsilon = 1e-9 * motion.duration
    marks = motion._mark_times()
    jerk = motion.state_at(np.concatenate((np.maximum(marks - epsilon, 0.0),
                                           np.minimum(marks + epsilon, motion.duration))))[3]
    expected = motion_module._merged_steps(
        law.times[1:-1] * factor, np.abs(np.diff(law.jerk)) / factor ** 3, marks, jerk,
        epsilon, float(motion.duration))
    found = motion.jerk_steps()
    assert marks.size >= 2
    assert all(np.array_equal(mine, theirs) for mine, theirs in zip(found, expected))


@pytest.mark.parametrize('factor', [1.0, 1.37])
def test_sorted_law_rows_are_the_path_state_bit_for_bit(timed, factor):
    motion = timed.scaled(factor)
    law = motion.law
    t = np.linspace(0.0, motion.duration, 1001)
    rows, pieces = np.empty((4, t.size)), np.empty(t.size, np.int64)
    inner = np.ascontiguousarray(law.times[1:-1] * factor)
    motion_module._sorted_law_rows(t, float(motion.duration), factor, factor ** 2,
                                   factor ** 3, law.times, law.s0, law.v0, law.a0, law.jerk,
                                   inner, rows, pieces)
    assert all(np.array_equal(found, expected)
               for found, expected in zip(rows, motion.path_state(t)))
    assert np.array_equal(pieces, np.searchsorted(inner, t, side='right'))
