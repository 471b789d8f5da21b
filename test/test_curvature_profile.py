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

"""The curvature profile's compiled and tabulated parts against plain computations of the same."""

import dataclasses

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import motion as motion_module
from ellipath_ros.core.curvature_profile import (
    _arc_cartesian_peaks, _cap_rate, _CurvatureArcLaw, _CurvatureSequence, _rule_peaks,
    _trapezoid_lengths, curvature_nodes)
from ellipath_ros.core.geometry import (arc_for_policy, ArcPolicy, EllipticArc, plan_path,
                                        radius_of_curvature_derivatives)
from ellipath_ros.core.planner import _check_reach_and_speed_cap, PlannerConfig
from ellipath_ros.core.timing import time_motion
import numpy as np
import pytest

# (l, h, k) [m]: the paper's example, a round arc, a thin one (a/b about 31, beyond the p99
# of random pairs) and a thin steep one.
ARCS = [(0.15, 0.025, 0.1), (0.15, 0.0, 0.15), (0.3, 0.05, 0.01), (0.3, -0.1, 0.02)]
GL_NODES, GL_WEIGHTS = np.polynomial.legendre.leggauss(40)


def elapsed_by_quadrature(arc, rate, theta_start, theta):
    """Return t(theta) = (a b / K) * integral of sigma**-3 from theta to theta_start."""
    edges = np.linspace(theta_start, theta, 129)
    half = 0.5 * (edges[1:] - edges[:-1])
    nodes = 0.5 * (edges[1:] + edges[:-1])[:, None] + half[:, None] * GL_NODES
    sigma = np.sqrt((arc.a * np.sin(nodes)) ** 2 + (arc.b * np.cos(nodes)) ** 2)
    return arc.a * arc.b / rate * float(np.sum(np.abs(half)[:, None] * sigma ** -3 * GL_WEIGHTS))


def law_on(l_, h, k, start_share=0.0, end_share=1.0, rate=3.0):
    arc = EllipticArc(l_, h, k)
    return _CurvatureArcLaw(arc, rate, 0.025, arc.theta_T1 - start_share * np.pi,
                            arc.theta_T1 - end_share * np.pi)


@pytest.mark.parametrize('shares', [(0.0, 1.0), (0.02, 0.9)])
@pytest.mark.parametrize('l_,h,k', ARCS)
def test_theta_of_t_inverts_the_elapsed_time(l_, h, k, shares):
    """The interpolated theta(t) lies on t(theta) computed by another quadrature."""
    law = law_on(l_, h, k, *shares)
    t = np.random.default_rng(7).uniform(0.0, law.duration, 60)
    theta = law.theta(t)
    elapsed = np.array([elapsed_by_quadrature(law.arc, law.rate, law.theta_start, value)
                        for value in theta])
    _, speed, _, _ = law.state(t)
    # As a distance along the path: within 1e-12 m (the table's own error is ~1e-13 m).
    assert np.max(np.abs(elapsed - t) * speed) < 1e-12
    assert law.duration == pytest.approx(
        elapsed_by_quadrature(law.arc, law.rate, law.theta_start, law.theta_end), rel=1e-12)


@pytest.mark.parametrize('l_,h,k', ARCS)
def test_states_follow_the_rule_at_the_interpolated_theta(l_, h, k):
    """The law's s is the arc length to theta(t); s', s'' and s''' follow the rule's rates."""
    law = law_on(l_, h, k)
    arc = law.arc
    t = np.linspace(0.0, law.duration, 2001)
    theta = law.theta(t)
    s, speed, accel, jerk = law.state(t)
    np.testing.assert_allclose(s, 0.025 + arc.s_from_t(arc.t_from_theta(theta)), rtol=0.0,
                               atol=1e-12)
    sigma = np.sqrt((arc.a * np.sin(theta)) ** 2 + (arc.b * np.cos(theta)) ** 2)
    np.testing.assert_allclose(speed, law.rate * sigma ** 4 / (arc.a * arc.b), rtol=1e-13)
    # s', s'' and s''' against central differences of s, s' and s'' (a step small beside the
    # panels; the bound covers the differences' own truncation error).
    step = 1e-6 * law.duration
    inner = t[1:-1]
    ahead, behind = law.state(inner + step), law.state(inner - step)
    for row, rate in enumerate((speed, accel, jerk)):
        np.testing.assert_allclose((ahead[row] - behind[row]) / (2 * step), rate[1:-1],
                                   rtol=0.0, atol=1e-4 * np.max(np.abs(rate)) + 1e-9)


def test_law_ends_on_its_bounds_and_clips_outside():
    law = law_on(*ARCS[0], 0.02, 0.9)
    theta = law.theta(np.array([-1.0, 0.0, law.duration, law.duration + 1.0]))
    assert theta[0] == theta[1] == law.theta_start
    assert theta[2] == theta[3] == pytest.approx(law.theta_end, abs=1e-14)


def test_order_of_the_times_does_not_change_the_states():
    """Sorted times step from panel to panel, others bisect: the same numbers either way."""
    law = law_on(*ARCS[2])
    t = np.random.default_rng(3).uniform(0.0, law.duration, 500)
    order = np.argsort(t)
    for shuffled, ordered in zip(law.state(t), law.state(t[order])):
        assert np.array_equal(shuffled[order], ordered)


def nodes_by_geometry(arc, r):
    """Return the paper's Steps 3-8 as a plain loop over geometry's radius of curvature."""
    theta, nodes = arc.theta_T1, [arc.theta_T1]
    while theta > arc.theta_T2:
        theta -= r * float(arc.radius_of_curvature(theta))
        nodes.append(theta)
    nodes[-1] = arc.theta_T2
    return np.array(nodes)


@pytest.mark.parametrize('r', [0.77, 0.05, 3.0])
@pytest.mark.parametrize('l_,h,k', ARCS)
def test_compiled_node_list_is_the_plain_loop_bit_for_bit(l_, h, k, r):
    arc = EllipticArc(l_, h, k)
    assert np.array_equal(curvature_nodes(arc, r), nodes_by_geometry(arc, r))


def peaks_by_geometry(arc, theta):
    """Return |v|, |a|, |j| of the rule at K = 1 from geometry's functions, in NumPy."""
    rho, rho_1, rho_2 = radius_of_curvature_derivatives(arc.a, arc.b, theta)
    w1, w2, w3 = -rho, rho * rho_1, -rho * (rho_1 ** 2 + rho * rho_2)
    p = arc.point(arc.t_from_theta(theta))
    d1 = arc.derivative(arc.t_from_theta(theta))
    velocity = d1 * w1[:, None]
    accel = -p * (w1 ** 2)[:, None] + d1 * w2[:, None]
    jerk = -d1 * (w1 ** 3)[:, None] - 3.0 * p * (w1 * w2)[:, None] + d1 * w3[:, None]
    return [np.linalg.norm(value, axis=1) for value in (velocity, accel, jerk)]


@pytest.mark.parametrize('l_,h,k', ARCS)
def test_compiled_peaks_are_numpys_to_rounding(l_, h, k):
    """
    K (hence every duration) depends on these maxima: the kernel must not move them.

    Equal to the last bit where NumPy's sine and cosine are glibc's; on a CPU with AVX-512
    NumPy (2.x) takes its own SIMD ones, a few units in the last place apart, which the jerk's
    cancellations widen to 31 ulp (seen on 53 of 1,001 samples): 1e-13 is about 450 ulp.
    """
    arc = EllipticArc(l_, h, k)
    theta = np.linspace(arc.theta_T1, arc.theta_T2, 1001)
    found = _arc_cartesian_peaks(arc, theta)
    for value, expected in zip(found[:3], peaks_by_geometry(arc, theta)):
        np.testing.assert_allclose(value, expected, rtol=1e-13, atol=0.0)
    sigma, sigma_1, _ = arc.sigma(theta)
    np.testing.assert_allclose(found[3], sigma, rtol=1e-15)
    np.testing.assert_allclose(found[4], sigma_1, rtol=1e-12, atol=1e-15)


def test_screened_peaks_are_the_exact_ones_bit_for_bit():
    """
    K depends on the peaks: screening the samples must find the exact samples' maxima.

    The profile's grid on the test arcs and on random ones of every arc policy (round,
    thin, steep), also where its first sample is the largest (T1 on a steep arc).
    """
    rng = np.random.default_rng(17)
    arcs = [EllipticArc(*values) for values in ARCS]
    for kind in ('paper', 'apex_clearance', 'min_radius'):
        for _ in range(20):
            half_width = 10.0 ** rng.uniform(-1.7, -0.3)
            arcs.append(arc_for_policy(half_width, rng.uniform(-1.0, 1.0) * half_width,
                                       ArcPolicy(kind=kind, apex_clearance=0.05,
                                                 min_radius=0.002)))
    for arc in arcs:
        theta = np.linspace(arc.theta_T1, arc.theta_T2, 4001)
        exact = _arc_cartesian_peaks(arc, theta)
        peaks, rows = _rule_peaks(arc, theta)
        assert peaks.tolist() == [*exact[:3].max(axis=1), exact[0, 0]]
        assert np.array_equal(rows[1:], exact[3:])
        np.testing.assert_allclose(rows[0], exact[0], rtol=1e-14, atol=0.0)


@pytest.mark.parametrize('cap_name', ['falling', 'dip', 'constant'])
def test_speed_cap_rate_is_the_minimum_over_all_samples(cap_name):
    """The shortlist by approximate arc length finds the exact minimum of cap(s) / speed."""
    path = plan_path([0, 0, -0.8], [0.3, 0, -0.75])
    arc = path.arc
    c1 = path.segment_lengths[0]
    caps = {'falling': lambda s: 3.0 - 4.0 * s,
            'dip': lambda s: 1.0 + 50.0 * (s - c1 - 0.1234) ** 2,
            'constant': lambda s: np.full_like(s, 2.0)}
    theta = np.linspace(arc.theta_T1, arc.theta_T2, 4001)
    speed, _, _, sigma, sigma_1 = _arc_cartesian_peaks(arc, theta)
    s = c1 + arc.s_from_t(arc.t_from_theta(theta))
    expected = np.min(caps[cap_name](s) / speed)
    found = _cap_rate(path, caps[cap_name], theta, speed, sigma, sigma_1)
    assert found == pytest.approx(expected, rel=1e-14)


def test_law_at_another_rate_keeps_the_time_table_bit_for_bit():
    law = law_on(*ARCS[0], rate=1.0)
    for rate in (0.37, 3.0):
        reused = law.at_rate(rate, 0.01)
        fresh = _CurvatureArcLaw(law.arc, rate, 0.01, law.theta_start, law.theta_end)
        assert np.array_equal(reused._times, fresh._times)
        assert reused.duration == pytest.approx(law.duration / rate, rel=1e-14)


def test_trapezoid_lengths_are_the_numpy_formula_bit_for_bit():
    path = plan_path([0, 0, -0.8], [0.3, 0, -0.75])
    arc, c1 = path.arc, path.segment_lengths[0]
    theta = np.linspace(arc.theta_T1, arc.theta_T2, 4001)
    _, _, _, sigma, sigma_1 = _arc_cartesian_peaks(arc, theta)
    step = theta[:-1] - theta[1:]
    pieces = 0.5 * step * (sigma[:-1] + sigma[1:]) - step ** 2 / 12.0 * (sigma_1[:-1]
                                                                         - sigma_1[1:])
    expected = c1 + np.concatenate(([0.0], np.cumsum(pieces)))
    found = np.empty(theta.size)
    _trapezoid_lengths(theta, sigma, sigma_1, c1, found)
    assert np.array_equal(found, expected)
    # Within the arc's length of the exact arc length (the rule's error is ~h**4).
    np.testing.assert_allclose(found, c1 + arc.s_from_t(arc.t_from_theta(theta)), rtol=0,
                               atol=1e-9)


def test_sequence_states_in_one_pass_equal_each_laws_bit_for_bit():
    # The curvature profile's sequence evaluates all its laws in one compiled pass: the
    # same numbers as the generic sequence, which calls each law's own state.
    config = dataclasses.replace(PlannerConfig(), profile='curvature', join='paper')
    rng = np.random.default_rng(31)
    for pick, place in random_pairs(8, seed=12):
        path = plan_path(pick, place, config.pick_clearance, config.place_clearance,
                         config.arc, config.join, config.join_tolerance)
        sequence = time_motion(path, config.limits, profile='curvature', r=config.curvature_r,
                               speed_cap=_check_reach_and_speed_cap(path, config)).law
        assert isinstance(sequence, _CurvatureSequence)
        duration = sequence.duration
        bounds = sequence.bounds()[0]
        for t in (np.sort(rng.uniform(0.0, duration, 400)), rng.uniform(-0.1, 1.1, 400) * duration,
                  np.concatenate((bounds, bounds - 1e-9 * duration, bounds + 1e-9 * duration)),
                  np.array(sequence._starts)):
            found = sequence.state(t)
            expected = motion_module._Sequence.state(sequence, t)
            assert all(np.array_equal(mine, theirs) for mine, theirs in zip(found, expected))


def test_sequence_newton_steps_in_one_pass_equal_the_array_steps_bit_for_bit():
    config = dataclasses.replace(PlannerConfig(), profile='curvature', join='paper')
    for pick, place in random_pairs(8, seed=13):
        path = plan_path(pick, place, config.pick_clearance, config.place_clearance,
                         config.arc, config.join, config.join_tolerance)
        sequence = time_motion(path, config.limits, profile='curvature', r=config.curvature_r,
                               speed_cap=_check_reach_and_speed_cap(path, config)).law
        lengths = np.array(path.segment_ends[1:3])
        for factor in (1.0, 1.37):
            duration = sequence.duration * factor
            # A first guess inside the motion, and one with a time beyond it.
            for guess in (np.array([0.3, 0.7]) * duration, np.array([-0.01, 1.2]) * duration):
                found = sequence.newton_times(lengths, guess, factor, duration)
                expected = motion_module._Sequence.newton_times(sequence, lengths, guess,
                                                                factor, duration)
                assert np.array_equal(found, expected)
                assert np.array_equal(np.signbit(found), np.signbit(expected))
