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

"""The G2 join: continuity, distance to the paper's path, exact verticals, timing through it."""

import functools
import math

from ellipath_ros.core import geometry, optimal_profile
from ellipath_ros.core.errors import DegenerateGeometryError, InvalidInputError
from ellipath_ros.core.geometry import ArcPolicy, blend_arc, BlendedArc, EllipticArc, plan_path
from ellipath_ros.core.limits import CartesianLimits
from ellipath_ros.core.timing import time_motion
import numpy as np
import pytest

APEX = ArcPolicy('apex_clearance', apex_clearance=0.025)
CASES = {
    'paper': ([0, 0, -0.8], [0.3, 0, -0.75], ArcPolicy()),
    'cycle_25_305_25': ([0, 0, -0.8], [0.305, 0, -0.8], APEX),
    'h_negative': ([0.05, 0.1, -0.75], [-0.2, -0.1, -0.85], ArcPolicy()),
    'steep_apex': ([0, 0, -0.9], [0.05, 0, -0.7], APEX),
    'wide_min_radius': ([-0.3, 0, -0.85], [0.3, 0.1, -0.8], ArcPolicy('min_radius')),
}


@functools.lru_cache(maxsize=None)
def path_of(name, join='g2', tolerance=5e-4):
    pick, place, policy = CASES[name]
    return plan_path(pick, place, 0.025, 0.02, policy, join, tolerance)


def joint_parameters(bend):
    """Parameters t of T1, the two transition ends and T2."""
    return (math.pi, math.pi - bend.span_1, bend.span_2, 0.0)


def test_transitions_bend_one_way_on_random_tight_arcs():
    """
    The transitions never turn the curvature negative (a slight S), even on tight, lopsided arcs.

    Half-widths, rises and conjugate half-axes drawn over the range of the workspace's legs,
    tight arcs (k of a few mm) included, where an unconstrained long transition bends the other
    way; the curvature is sampled far more densely than the design checks it.
    """
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(100):
        ellipse = EllipticArc(rng.uniform(0.02, 0.2), rng.uniform(-0.12, 0.12),
                              rng.uniform(0.004, 0.05))
        try:
            bend = blend_arc(ellipse)
        except DegenerateGeometryError:
            continue
        kappa = bend.curvature_and_rate(np.linspace(math.pi, 0.0, 20001))[0]
        # T1 and T2 have curvature 0 up to rounding.
        assert kappa.min() >= -1e-9 * kappa.max()
        checked += 1
    assert checked >= 90


@pytest.mark.parametrize('name', CASES)
def test_curvature_is_continuous_at_every_joint(name):
    path = path_of(name)
    bend = path.bend
    assert isinstance(bend, BlendedArc)
    scale = float(np.max(bend.curvature_and_rate(np.linspace(math.pi, 0.0, 2001))[0]))
    t1, inner_1, inner_2, t2 = joint_parameters(bend)
    # At T1 and T2 the line's curvature is 0: so is the bend's.
    kappa_ends = bend.curvature_and_rate(np.array([t1, t2]))[0]
    assert np.abs(kappa_ends).max() <= 1e-9 * scale
    # Where the transitions meet the ellipse: position, tangent and curvature agree.
    for t_join, inside in ((inner_1, 1e-13), (inner_2, -1e-13)):
        here = np.array([t_join + inside])
        bent = bend.derivatives(here)
        plain = bend.ellipse.derivatives(here)
        np.testing.assert_allclose(bent[0], plain[0], rtol=0, atol=1e-15)
        np.testing.assert_allclose(bent[1], plain[1], rtol=0, atol=1e-12)
        kappa_bent = bend.curvature_and_rate(here)[0][0]
        kappa_plain = bend.ellipse.curvature_and_rate(here)[0][0]
        assert abs(kappa_bent - kappa_plain) <= 1e-9 * kappa_plain
    # Through the composite path: the unit tangent and the curvature vector have no jump.
    for s_join in path.segment_ends[1:3]:
        samples = path.at_lengths(np.array([s_join - 1e-12, s_join + 1e-12]))
        np.testing.assert_allclose(samples.tangent[0], samples.tangent[1], atol=1e-9)
        assert np.linalg.norm(samples.curvature[0] - samples.curvature[1]) <= 1e-9 * scale


def test_ellipse_curvature_matches_its_closed_form():
    """The generic curvature formula against the ellipse's k l / |P'|**3 and eq. (34)."""
    arc = path_of('paper', 'paper').arc
    t = np.linspace(math.pi, 0.0, 101)
    kappa = arc.curvature_and_rate(t)[0]
    np.testing.assert_allclose(kappa, 1.0 / arc.radius_of_curvature(t + arc.theta_T2),
                               rtol=1e-12)


def test_transition_shape_end_conditions_derivatives_and_peak():
    """
    The transition shape f: its conditions at both ends, its derivatives and its stated peak.

    f(0) = f'(0) = 0 and f''(0) = 1 cancel the ellipse's curvature at T1/T2; f and its first
    three derivatives vanish at u = 1 (continuous curvature and rate where it meets the
    ellipse); each derivative is checked against central differences of the one before, and
    the closed-form peak (which sizes the always-safe span) against a dense grid.
    """
    u = np.linspace(0.0, 1.0, 200001)
    values = geometry._blend_shape(u)
    start = [float(value[0]) for value in values[:3]]
    assert start == pytest.approx([0.0, 0.0, 1.0], abs=1e-15)
    assert max(abs(float(value[-1])) for value in values) <= 1e-12
    step = u[1] - u[0]
    for lower, higher in zip(values, values[1:]):
        differences = (lower[2:] - lower[:-2]) / (2.0 * step)
        scale = np.abs(higher).max()
        np.testing.assert_allclose(differences, higher[1:-1], atol=1e-7 * scale)
    peak = float(values[0].max())
    assert peak <= geometry._BLEND_PEAK * (1.0 + 1e-12)
    assert peak >= geometry._BLEND_PEAK * (1.0 - 1e-9)


@pytest.mark.parametrize('name', CASES)
@pytest.mark.parametrize('tolerance', [1e-4, 5e-4, 2e-3])
def test_g2_path_stays_within_the_tolerance_of_the_papers(name, tolerance):
    g2, paper = path_of(name, 'g2', tolerance), path_of(name, 'paper')
    s = np.linspace(0.0, g2.length, 801)
    points = g2.at_lengths(s).position
    # The paper's path as a dense polyline of exact points (lines and ellipse), 1 um apart;
    # each point is compared with the stretch within 4 mm of its arc length.
    spacing = 1e-6
    reference = paper.at_lengths(np.arange(0.0, paper.length + spacing, spacing)).position
    window = int(0.004 / spacing)
    distance = np.empty(s.size)
    for index, (s_point, point) in enumerate(zip(s, points)):
        middle = int(s_point * paper.length / g2.length / spacing)
        near = reference[max(middle - window, 0):middle + window]
        distance[index] = np.linalg.norm(near - point, axis=1).min()
    assert distance.max() <= tolerance
    # The transitions use the tolerance (a longer transition bends more gently).
    assert distance.max() >= 0.3 * tolerance or max(g2.bend.span_1, g2.bend.span_2) > 1.0


@pytest.mark.parametrize('name', CASES)
def test_vertical_segments_are_exact(name):
    path = path_of(name)
    c1, _, c2 = path.segment_lengths
    assert (c1, c2) == (0.025, 0.02)
    s = np.linspace(0.0, c1, 51)
    samples = path.at_lengths(s)
    np.testing.assert_array_equal(samples.position[:, :2], np.tile(path.pick[:2], (51, 1)))
    np.testing.assert_allclose(samples.position[:, 2], path.pick[2] + s, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(samples.tangent, np.tile([0.0, 0.0, 1.0], (51, 1)))
    assert not samples.curvature.any()
    s = np.linspace(path.length - c2, path.length, 51)
    samples = path.at_lengths(s)
    np.testing.assert_array_equal(samples.position[:, :2], np.tile(path.place[:2], (51, 1)))
    np.testing.assert_allclose(samples.position[:, 2], path.place[2] + path.length - s,
                               rtol=0, atol=1e-15)
    # The apex height is the paper's (the transitions only bend horizontally).
    assert path.apex[2] == path_of(name, 'paper').apex[2]


@pytest.mark.parametrize('name', ['paper', 'h_negative', 'steep_apex'])
def test_bend_derivatives_match_finite_differences_of_positions(name):
    """Tangent, curvature vector and its rate by s against differences of exact positions."""
    path = path_of(name)
    bend = path.bend
    ends = path.segment_ends
    s = np.linspace(ends[1] + 1e-4, ends[2] - 1e-4, 301)
    # dkappa/ds steps where the transitions meet the ellipse: keep the stencils off them.
    inner = ends[1] + bend.s_from_t(np.array([math.pi - bend.span_1, bend.span_2]))
    s = s[np.abs(s[:, None] - inner).min(axis=1) > 1e-4]
    samples = path.at_lengths(s)

    def stencil(h):
        return [path.at_lengths(s + k * h).position for k in (-2, -1, 0, 1, 2)]
    at = stencil(1e-6)
    first = (at[3] - at[1]) / 2e-6
    at = stencil(1e-5)
    second = (at[3] - 2 * at[2] + at[1]) / 1e-10
    at = stencil(2e-5)
    third = (at[4] - 2 * at[3] + 2 * at[1] - at[0]) / (2 * 2e-5 ** 3)
    scale_2 = np.abs(samples.curvature).max()
    scale_3 = np.abs(samples.curvature_rate).max()
    np.testing.assert_allclose(first, samples.tangent, atol=1e-6)
    np.testing.assert_allclose(second, samples.curvature, atol=1e-4 * scale_2)
    np.testing.assert_allclose(third, samples.curvature_rate, atol=2e-3 * scale_3)


@functools.lru_cache(maxsize=None)
def motion_of(name):
    return time_motion(path_of(name), CartesianLimits())


@pytest.mark.parametrize('name', CASES)
def test_g2_motion_has_no_acceleration_step(name):
    motion = motion_of(name)
    assert motion.accel_jump_T1 == 0.0 and motion.accel_jump_T2 == 0.0
    duration = motion.duration
    t = np.linspace(0.0, duration, int(duration / 1e-5) + 1)
    _, _, acceleration, jerk = motion.state_at(t)
    # Bounded jerk everywhere: no sample-to-sample acceleration change beyond jerk * dt.
    steps = np.linalg.norm(np.diff(acceleration, axis=0), axis=1) / (t[1] - t[0])
    assert steps.max() <= 1.01 * CartesianLimits().max_jerk
    assert np.linalg.norm(jerk, axis=1).max() <= CartesianLimits().max_jerk


def test_g2_ends_entered_braking_only_where_that_is_faster(monkeypatch):
    """
    On the 25-305-25 cycle the lift still brakes at T1 (and the descent starts speeding up).

    With the curvature 0 at a G2 end nothing forces s'' = 0 there; the probed
    end state must make the whole motion faster than entering at rest
    acceleration, and s'' must be continuous through T1 and T2 (no step).
    """
    def accelerations_at_the_ends(motion):
        lift, arc, _ = motion.segment_durations
        ends = np.array([lift, lift + arc])
        return [motion.path_state(ends + side)[2] for side in (-1e-7, 1e-7)]

    path = path_of('cycle_25_305_25')
    probed = time_motion(path, CartesianLimits())
    before, after = accelerations_at_the_ends(probed)
    assert before[0] < -1.0 and before[1] > 1.0
    np.testing.assert_allclose(after, before, atol=1e-3)
    monkeypatch.setattr(optimal_profile, '_END_ACCEL_SHARES', (0.0,))
    at_rest = time_motion(path, CartesianLimits())
    np.testing.assert_allclose(accelerations_at_the_ends(at_rest), 0.0, atol=1e-3)
    assert probed.duration < at_rest.duration


@pytest.mark.parametrize('name', ['paper', 'h_negative'])
def test_jerk_matches_finite_differences_of_positions(name):
    """The jerk of the timed motion against third differences of exact positions."""
    motion = motion_of(name)
    law = motion.law
    # Mid-points of constant-jerk pieces long enough for the difference stencil.
    times = law.times * motion.time_scale
    starts, lengths = times[:-1], np.diff(times)
    h = 2e-5
    t = (starts + 0.5 * lengths)[lengths > 10 * h]
    # The curvature rate steps where the transitions meet the ellipse: so does the jerk.
    bend, ends = motion.path.bend, motion.path.segment_ends
    inner = ends[1] + bend.s_from_t(np.array([math.pi - bend.span_1, bend.span_2]))
    low, high = motion.path_state(t - 2 * h)[0], motion.path_state(t + 2 * h)[0]
    t = t[~((low[:, None] <= inner) & (inner <= high[:, None])).any(axis=1)]
    assert t.size > 20
    at = [motion.state_at(t + k * h)[0] for k in (-2, -1, 0, 1, 2)]
    third = (at[4] - 2 * at[3] + 2 * at[1] - at[0]) / (2 * h ** 3)
    jerk = motion.state_at(t)[3]
    np.testing.assert_allclose(third, jerk, atol=5e-3 * CartesianLimits().max_jerk)


def test_curvature_profile_needs_the_paper_join():
    with pytest.raises(InvalidInputError, match='^join: expected paper'):
        time_motion(path_of('paper'), profile='curvature')


@pytest.mark.parametrize('join, tolerance, message', [
    ('g3', 5e-4, '^join: expected'),
    ('g2', 0.0, '^join_tolerance: expected'),
    ('g2', 0.5, '^join_tolerance: expected'),
])
def test_invalid_join_arguments(join, tolerance, message):
    with pytest.raises(InvalidInputError, match=message):
        plan_path([0, 0, -0.8], [0.3, 0, -0.75], join=join, join_tolerance=tolerance)
