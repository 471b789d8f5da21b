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

"""Timing laws: limits on the continuous motion, continuity, the paper's nodes, the API."""

import functools
import math

from ellipath_ros.core import optimal_profile
from ellipath_ros.core.curvature_profile import curvature_nodes
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.geometry import ArcPolicy, plan_path
from ellipath_ros.core.limits import CartesianLimits
from ellipath_ros.core.motion import PROFILES, TimedMotion
from ellipath_ros.core.timing import time_motion
import numpy as np
import pytest

# Fine sampling of the continuous motion [s].
PERIOD = 1e-4
# Relative slack on a limit for rounding only (the planner aims below the limits).
ROUNDING = 1e-9
LIMITS = CartesianLimits()
APEX = ArcPolicy('apex_clearance', apex_clearance=0.025)

PATHS = {
    'paper': lambda: plan_path([0, 0, -0.8], [0.3, 0, -0.75]),
    'cycle_25_305_25': lambda: plan_path([0, 0, -0.8], [0.305, 0, -0.8], policy=APEX),
    'h_negative': lambda: plan_path([0, 0, -0.75], [0.3, 0, -0.8]),
    'h_zero_paper': lambda: plan_path([0, 0, -0.8], [0.3, 0, -0.8]),
    'vertical': lambda: plan_path([0.1, 0, -0.9], [0.1, 0, -0.7]),
    'clearance_0': lambda: plan_path([0, 0, -0.8], [0.3, 0, -0.75], 0.0, 0.0),
    'clearance_1mm': lambda: plan_path([0, 0, -0.8], [0.3, 0, -0.75], 0.001, 0.001),
    'steep_apex': lambda: plan_path([0, 0, -0.9], [0.05, 0, -0.7], policy=APEX),
}
CASES = [(name, profile) for name in PATHS for profile in PROFILES]


@functools.lru_cache(maxsize=None)
def motion_of(name, profile, max_accel_jump=25.0):
    """Return the motion of a named path (computed once)."""
    return time_motion(PATHS[name](), CartesianLimits(max_accel_jump=max_accel_jump),
                       profile=profile)


@functools.lru_cache(maxsize=None)
def samples_of(name, profile):
    """Return (t, s, s', s'', s''', position, velocity, acceleration, jerk), fine samples."""
    motion = motion_of(name, profile)
    t = np.linspace(0.0, motion.duration, int(math.ceil(motion.duration / PERIOD)) + 1)
    return (t,) + motion.path_state(t) + motion.state_at(t)


def one_sided(motion, t_join, epsilon=1e-7):
    """Return the Cartesian state just before and just after ``t_join``."""
    t = np.array([t_join - epsilon, t_join + epsilon])
    return motion.state_at(np.clip(t, 0.0, motion.duration))


@pytest.mark.parametrize('name,profile', CASES)
def test_limits_hold_on_fine_samples(name, profile):
    _, _, _, _, _, _, velocity, acceleration, jerk = samples_of(name, profile)
    assert np.linalg.norm(velocity, axis=1).max() <= LIMITS.max_speed * (1 + ROUNDING)
    assert np.linalg.norm(acceleration, axis=1).max() <= LIMITS.max_accel * (1 + ROUNDING)
    assert np.linalg.norm(jerk, axis=1).max() <= LIMITS.max_jerk * (1 + ROUNDING)


@pytest.mark.parametrize('name,profile', CASES)
def test_progress_is_monotone_from_rest_to_rest(name, profile):
    motion = motion_of(name, profile)
    t, s, v, a, _, position, _, _, _ = samples_of(name, profile)
    assert v.min() >= -1e-12
    assert np.all(np.diff(s) >= -1e-12)
    assert s[0] == pytest.approx(0.0, abs=1e-12)
    assert s[-1] == pytest.approx(motion.path.length, abs=1e-9)
    assert abs(v[0]) + abs(a[0]) < 1e-9 and abs(v[-1]) + abs(a[-1]) < 1e-6
    np.testing.assert_allclose(position[0], motion.path.pick, atol=1e-12)
    np.testing.assert_allclose(position[-1], motion.path.place, atol=1e-9)
    assert motion.duration == pytest.approx(t[-1])
    assert motion.segment_durations.sum() == pytest.approx(motion.duration)


@pytest.mark.parametrize('name,profile', CASES)
def test_velocity_and_acceleration_are_continuous(name, profile):
    """Between samples v changes by at most a_max dt, s'' by at most max|s'''| dt, ..."""
    motion = motion_of(name, profile)
    t, _, _, a, j, _, velocity, acceleration, _ = samples_of(name, profile)
    step = np.diff(t).max()
    assert np.linalg.norm(np.diff(velocity, axis=0), axis=1).max() <= (
        LIMITS.max_accel * step * (1 + 1e-6))
    assert np.abs(np.diff(a)).max() <= np.abs(j).max() * step * (1 + 1e-6) + 1e-9
    jumps = np.linalg.norm(np.diff(acceleration, axis=0), axis=1)
    allowed = LIMITS.max_jerk * step * (1 + 1e-6)
    steps = jumps > allowed
    # ... and the acceleration vector by at most j_max dt except at the two joins, where it
    # steps by the amount the motion reports.
    assert steps.sum() <= 2
    assert jumps.max() <= max(motion.accel_jump_T1, motion.accel_jump_T2) + allowed


@pytest.mark.parametrize('name,profile', [case for case in CASES if case[0] != 'vertical'])
def test_joins_t1_t2_continuous_with_bounded_step(name, profile):
    motion = motion_of(name, profile)
    s_joins = motion.path.segment_ends[1:3]
    t_joins = (motion.segment_durations[0], motion.duration - motion.segment_durations[2])
    for s_join, t_join, reported in zip(s_joins, t_joins,
                                        (motion.accel_jump_T1, motion.accel_jump_T2)):
        assert motion.path_state([t_join])[0][0] == pytest.approx(s_join, abs=1e-9)
        _, velocity, acceleration, _ = one_sided(motion, t_join)
        assert np.linalg.norm(velocity[1] - velocity[0]) <= 1e-4
        step = np.linalg.norm(acceleration[1] - acceleration[0])
        assert step <= LIMITS.max_accel_jump * (1 + 1e-6)
        assert step == pytest.approx(reported, abs=2e-3)
        # The tangential acceleration is continuous: only the normal part steps.
        a_before, a_after = motion.path_state(
            np.clip([t_join - 1e-7, t_join + 1e-7], 0.0, motion.duration))[2]
        assert abs(a_after - a_before) <= 1e-2


@pytest.mark.parametrize('profile', PROFILES)
@pytest.mark.parametrize('max_accel_jump', [5.0, 0.0])
def test_smaller_accel_jump_is_kept(profile, max_accel_jump):
    motion = motion_of('paper', profile, max_accel_jump)
    assert max(motion.accel_jump_T1, motion.accel_jump_T2) <= max_accel_jump * (1 + 1e-9)
    _, _, acceleration, _ = one_sided(motion, motion.segment_durations[0])
    assert np.linalg.norm(acceleration[1] - acceleration[0]) <= max_accel_jump + 1e-3
    if max_accel_jump == 0.0:
        assert motion.path_state([motion.segment_durations[0]])[1][0] == pytest.approx(
            0.0, abs=1e-9)


def test_time_optimal_is_much_faster_than_the_papers_profile():
    optimal = motion_of('paper', 'time_optimal')
    paper = motion_of('paper', 'curvature')
    assert optimal.duration < 0.3
    assert paper.duration > 5.0 * optimal.duration


def test_time_optimal_meets_the_cartesian_limits_closely():
    """Close to the limits somewhere (a timing law far below them would not be optimal)."""
    metrics = motion_of('cycle_25_305_25', 'time_optimal').metrics()
    assert metrics['peak_accel'] > 0.95 * LIMITS.max_accel
    assert metrics['peak_jerk'] > 0.95 * LIMITS.max_jerk
    assert metrics['accel_jump_T1'] > 0.95 * LIMITS.max_accel_jump


def test_papers_example_has_80_nodes_and_the_last_is_clamped():
    arc = plan_path([0, 0, -0.8], [0.3, 0, -0.75]).arc
    nodes = curvature_nodes(arc, 0.77)
    assert nodes.size == 80
    assert nodes[0] == arc.theta_T1
    assert nodes[-1] == arc.theta_T2
    steps = -np.diff(nodes[:-1])
    np.testing.assert_allclose(steps, 0.77 * arc.radius_of_curvature(nodes[:-2]), rtol=1e-12)
    # Step 7 as written overshoots T2 with the last step; the clamp shortens it.
    assert nodes[-2] - 0.77 * arc.radius_of_curvature(nodes[-2]) < arc.theta_T2
    assert motion_of('paper', 'curvature').n_nodes == 80
    assert motion_of('paper', 'time_optimal').n_nodes is None


def test_curvature_profile_speed_follows_the_radius_of_curvature():
    """The rule's speed is K sigma**4 / (a b), proportional to rho**(4/3) along the arc."""
    motion = motion_of('paper', 'curvature')
    arc = motion.path.arc
    t = np.linspace(motion.segment_durations[0] + 0.05,
                    motion.duration - motion.segment_durations[2] - 0.05, 50)
    s, v, _, _ = motion.path_state(t)
    theta = arc.t_from_s(s - motion.path.segment_ends[1]) + arc.theta_T2
    ratio = v / arc.radius_of_curvature(theta) ** (4.0 / 3.0)
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-6)


@pytest.mark.parametrize('name,profile', [('paper', 'curvature'), ('paper', 'time_optimal'),
                                          ('clearance_0', 'curvature')])
def test_derivatives_match_finite_differences(name, profile):
    motion = motion_of(name, profile)
    t = np.linspace(0.01, motion.duration - 0.01, 400)
    h = 1e-6
    position, velocity, acceleration, _ = motion.state_at(t)
    ahead, behind = motion.state_at(t + h), motion.state_at(t - h)
    np.testing.assert_allclose((ahead[0] - behind[0]) / (2 * h), velocity, atol=1e-5)
    np.testing.assert_allclose((ahead[1] - behind[1]) / (2 * h), acceleration, atol=2e-2)
    s, v, a, _ = motion.path_state(t)
    s_ahead, v_ahead, _, _ = motion.path_state(t + h)
    np.testing.assert_allclose((s_ahead - s) / h, v, atol=1e-3)


def test_speed_cap_is_respected():
    path = plan_path([0, 0, -0.8], [0.3, 0, -0.75])
    s_dip = path.segment_ends[1] + 0.5 * path.segment_lengths[1]

    def cap(s):
        return 3.0 - 2.5 * np.exp(-((s - s_dip) / 0.03) ** 2)

    for profile in PROFILES:
        motion = time_motion(path, profile=profile, speed_cap=cap)
        t = np.linspace(0.0, motion.duration, int(motion.duration / PERIOD) + 1)
        s, v, _, _ = motion.path_state(t)
        assert np.max(v / cap(s)) <= 1.0 + ROUNDING
        assert motion.duration > motion_of('paper', profile).duration


def test_scaled_slows_down_uniformly():
    motion = motion_of('paper', 'time_optimal')
    factor = 1.7
    slow = motion.scaled(factor)
    assert isinstance(slow, TimedMotion)
    assert slow.duration == pytest.approx(factor * motion.duration)
    np.testing.assert_allclose(slow.segment_durations, factor * motion.segment_durations)
    assert slow.accel_jump_T1 == pytest.approx(motion.accel_jump_T1 / factor ** 2)
    t = np.linspace(0.0, motion.duration, 97)
    fast_state = motion.state_at(t)
    slow_state = slow.state_at(factor * t)
    for power, (fast, slow_value) in enumerate(zip(fast_state, slow_state)):
        np.testing.assert_allclose(slow_value, fast / factor ** power, atol=1e-9)
    assert slow.scaled(2.0).duration == pytest.approx(2.0 * slow.duration)
    assert motion.scaled(1.0).duration == motion.duration


def test_metrics_report_the_motion():
    motion = motion_of('paper', 'time_optimal')
    metrics = motion.metrics()
    assert set(metrics) == {'duration', 'segment_durations', 'peak_speed', 'peak_accel',
                            'peak_jerk', 'accel_jump_T1', 'accel_jump_T2'}
    _, _, _, _, _, _, velocity, acceleration, jerk = samples_of('paper', 'time_optimal')
    assert metrics['peak_speed'] == pytest.approx(np.linalg.norm(velocity, axis=1).max())
    assert metrics['peak_accel'] == pytest.approx(np.linalg.norm(acceleration, axis=1).max())
    assert metrics['peak_jerk'] == pytest.approx(np.linalg.norm(jerk, axis=1).max())
    assert metrics['duration'] == motion.duration
    assert metrics['segment_durations'] == motion.segment_durations.tolist()
    assert all(isinstance(value, float) for key, value in metrics.items()
               if key != 'segment_durations')


def test_vertical_move_has_one_segment_and_no_steps():
    motion = motion_of('vertical', 'time_optimal')
    assert motion.segment_durations[0] == motion.duration
    assert motion.segment_durations[1:].tolist() == [0.0, 0.0]
    assert motion.accel_jump_T1 == motion.accel_jump_T2 == 0.0
    down = time_motion(plan_path([0.1, 0, -0.7], [0.1, 0, -0.9]))
    assert down.segment_durations[2] == down.duration


@pytest.mark.parametrize('profile,message', [
    ('x', "profile: expected one of curvature, time_optimal, got 'x'"),
    (None, 'profile: expected one of curvature, time_optimal, got None'),
])
def test_invalid_profile(profile, message):
    with pytest.raises(InvalidInputError) as error:
        time_motion(PATHS['paper'](), profile=profile)
    assert str(error.value) == message


@pytest.mark.parametrize('r', [0.0, -0.77, math.nan, math.inf, 'a'])
def test_invalid_r(r):
    with pytest.raises(InvalidInputError, match='^r: expected'):
        time_motion(PATHS['paper'](), profile='curvature', r=r)
    with pytest.raises(InvalidInputError, match='^r: expected'):
        curvature_nodes(PATHS['paper']().arc, r)


def test_tiny_r_is_refused_before_building_a_huge_node_list():
    with pytest.raises(InvalidInputError, match='^r: expected a value giving at most'):
        curvature_nodes(PATHS['paper']().arc, 1e-6)


@pytest.mark.parametrize('field,value', [
    ('max_speed', 0.0), ('max_speed', -1.0), ('max_accel', math.nan), ('max_jerk', math.inf),
    ('max_accel_jump', -0.1), ('max_accel', 'fast'),
])
def test_invalid_limits(field, value):
    with pytest.raises(InvalidInputError, match=f'^{field}: expected'):
        CartesianLimits(**{field: value})


def test_invalid_arguments():
    path = PATHS['paper']()
    with pytest.raises(InvalidInputError, match='^path: expected a PickPlacePath'):
        time_motion('path')
    with pytest.raises(InvalidInputError, match='^limits: expected a CartesianLimits'):
        time_motion(path, {'max_speed': 1.0})
    with pytest.raises(InvalidInputError, match='^speed_cap: expected a callable'):
        time_motion(path, speed_cap=2.0)
    with pytest.raises(InvalidInputError, match='^speed_cap: expected positive'):
        time_motion(path, speed_cap=lambda s: np.zeros_like(s))
    with pytest.raises(InvalidInputError, match='^speed_cap: expected positive'):
        time_motion(path, speed_cap=lambda s: np.ones(3))
    motion = motion_of('paper', 'time_optimal')
    with pytest.raises(InvalidInputError, match='^t: expected'):
        motion.state_at([motion.duration + 1e-3])
    for times in ([math.nan], [0.0, math.nan, 0.1], [math.inf], [-math.inf, 0.0], [[0.0, 0.1]],
                  [-1e-6]):
        with pytest.raises(InvalidInputError, match='^t: expected'):
            motion.path_state(times)
    # Within 1e-9 of the duration outside it: the state at the end it is taken to.
    outside = [-1e-10 * motion.duration, motion.duration * (1.0 + 1e-10)]
    for mine, ends in zip(motion.path_state(outside), motion.path_state([0.0, motion.duration])):
        assert np.array_equal(mine, ends)
    assert motion.path_state(np.zeros(0))[0].shape == (0,)
    with pytest.raises(InvalidInputError, match='^factor: expected'):
        motion.scaled(0.5)
    with pytest.raises(InvalidInputError, match='^sample_period: expected'):
        motion.metrics(0.0)


@pytest.mark.parametrize('name', ['paper', 'cycle_25_305_25'])
@pytest.mark.parametrize('max_accel_jump,target', [(25.0, 1.15), (5.0, 1.25)])
def test_time_optimal_is_close_to_the_bound_without_jerk_limit(name, max_accel_jump, target):
    """No jerk-limited motion beats TOPP-RA's bound; ours stays within the target of it."""
    pytest.importorskip('toppra')
    from ellipath_ros.bench import topp_bound
    motion = motion_of(name, 'time_optimal', max_accel_jump)
    bound = topp_bound(motion.path, CartesianLimits(max_accel_jump=max_accel_jump))
    assert bound < motion.duration <= target * bound


def test_node_period_is_the_papers_time_step():
    """Delta t = r / K; the rule takes about one Delta t per node along the arc."""
    motion = motion_of('paper', 'curvature')
    arc_time = motion.segment_durations[1]
    assert motion.node_period == pytest.approx(arc_time / (motion.n_nodes - 1), rel=0.05)
    assert motion.scaled(2.0).node_period == pytest.approx(2.0 * motion.node_period)
    assert motion_of('paper', 'time_optimal').node_period is None


def test_curvature_profile_takes_the_documented_time_on_the_papers_example():
    """README and docs quote 2.2496 s for r = 0.77 (a slower law would break this)."""
    assert round(motion_of('paper', 'curvature').duration, 4) == 2.2496


def test_time_optimal_profile_depends_on_the_problem_only():
    """The same leg timed twice, and after other legs, gives the same pieces bit for bit."""
    def pieces(name):
        law = time_motion(PATHS[name](), LIMITS).law
        return [law.times, law.s0, law.v0, law.a0, law.jerk]

    first = pieces('paper')
    for other in ('steep_apex', 'h_negative', 'cycle_25_305_25'):
        pieces(other)
    for before, after in zip(first, pieces('paper')):
        assert np.array_equal(before, after)


def test_spent_step_budget_falls_back_to_the_sure_construction(monkeypatch):
    """A scan that runs out of steps hands over to the Ruckig-knot fallback, within limits."""
    path = PATHS['paper']()
    full = time_motion(path, LIMITS)
    monkeypatch.setattr(optimal_profile, '_STEP_BUDGET', 50)
    calls = []
    fallback = optimal_profile._ArcPlanner.fallback
    monkeypatch.setattr(optimal_profile._ArcPlanner, 'fallback',
                        lambda planner, *ends: calls.append(ends) or fallback(planner, *ends))
    slow = time_motion(path, LIMITS)
    assert len(calls) == 1
    # The fallback's knots rest at half the speed ceiling: slower than the scans.
    assert slow.duration > full.duration
    _, speed, accel, jerk = slow.sampled_norms()
    assert speed.max() <= LIMITS.max_speed * (1.0 + ROUNDING)
    assert accel.max() <= LIMITS.max_accel * (1.0 + ROUNDING)
    assert jerk.max() <= LIMITS.max_jerk * (1.0 + ROUNDING)


def _planner_with_arcs(arc_of_states):
    """Return an arc planner whose whole-arc solve is ``arc_of_states`` (for its retries)."""
    planner = object.__new__(optimal_profile._ArcPlanner)
    planner._arc = arc_of_states
    planner._half_spent = lambda: False
    return planner


def _arc_up_to(highest_entry, duration_of_entry, calls=None):
    """Return a stand-in for the whole-arc solve: entry speeds above ``highest_entry`` fail."""
    def arc(states):
        if calls is not None:
            calls.append(tuple(states))
        if states[0][0] > highest_entry:
            raise optimal_profile._EndTooFast(True)
        return ([(duration_of_entry(states[0][0]), 0.0, states[0][0], states[0][1], 0.0)],
                states[0], states[1])
    return arc


def test_end_speed_retries_bisect_towards_the_highest_that_serves():
    # 1.0 comes down by 0.8 to 0.32768 (0.4096 fails); three bisections bracket 0.36 within
    # an eighth of that step.
    planner = _planner_with_arcs(_arc_up_to(0.36, lambda speed: 1.0 - speed))
    _, entry, exit_state = planner.solve((1.0, 0.0), (0.5, 0.0))
    step = 0.4096 - 0.32768
    assert 0.36 - step / 8.0 <= entry[0] <= 0.36
    assert exit_state == (0.5, 0.0)


def test_end_speed_bisection_keeps_the_faster_arc():
    # A faster entry that makes the arc slower (a lower valley further in) is not kept.
    planner = _planner_with_arcs(_arc_up_to(0.36, lambda speed: speed))
    _, entry, _ = planner.solve((1.0, 0.0), (0.5, 0.0))
    assert entry[0] == pytest.approx(1.0 * 0.8 ** 5)


def test_entry_acceleration_the_arc_cannot_take_comes_down_to_0_first():
    """A failing end entered at s'' != 0 retries at s'' = 0 and the same speed, then slower."""
    calls = []
    planner = _planner_with_arcs(_arc_up_to(0.3, lambda speed: 1.0, calls))
    rows, entry, exit_state = planner.solve((0.4, -10.0), (0.5, 8.0))
    assert [state[0] for state in calls[:3]] == [(0.4, -10.0), (0.4, 0.0),
                                                 (pytest.approx(0.32), 0.0)]
    # The exit, which never failed, keeps its acceleration; the retried entry has none.
    assert 0.25 < entry[0] <= 0.3 and entry[1] == 0.0 and exit_state == (0.5, 8.0)
    assert rows[0][3] == 0.0


def _planner_probing(join, probe_times):
    """Return an arc planner on a ``join`` path whose probes take ``probe_times[s'']``."""
    planner = object.__new__(optimal_profile._ArcPlanner)
    planner.path = plan_path([0, 0, -0.8], [0.3, 0, -0.75], join=join)
    planner.limits = LIMITS
    planner._probe = lambda speed, accel, clearance, at_start, cap: probe_times[accel]
    return planner


@pytest.mark.parametrize('times, expected', [
    ({0.0: 1.0, -10.0: 0.9}, -10.0),
    ({0.0: 1.0, -10.0: 1.0}, 0.0),
    ({0.0: 1.0, -10.0: math.inf}, 0.0),
    ({0.0: math.inf, -10.0: math.inf}, 0.0),
])
def test_g2_end_keeps_the_faster_probed_acceleration_rest_on_ties(times, expected):
    # -10 m/s² is -0.2 max_accel at the default 50 m/s².
    assert LIMITS.max_accel == 50.0
    planner = _planner_probing('g2', times)
    assert planner.end_state(0.4, 0.025, True, None) == (0.4, expected)
    # At T2 the state is mirrored: braking into T1 is speeding up out of T2.
    assert planner.end_state(0.4, 0.025, False, None) == (0.4, -expected + 0.0)


def test_paper_join_is_entered_at_rest_acceleration_without_probes():
    planner = _planner_probing('paper', {})
    assert planner.end_state(0.4, 0.025, True, None) == (0.4, 0.0)
    assert planner.end_state(0.4, 0.025, False, None) == (0.4, 0.0)


def test_valley_speed_retries_bisect_towards_the_highest_that_serves():
    # A valley at s = 0.5 whose two parts are solved only at speeds up to 0.5: 0.9 and 0.54
    # fail, 0.324 serves, three bisections bracket 0.5 within an eighth of that step.
    def hill(s_a, state_a, s_b, state_b, free_a, free_b, depth):
        speed = state_b[0] if s_b == 0.5 else state_a[0]
        if speed > 0.5:
            raise optimal_profile._NoMotion()
        return [(1.0 - speed, s_a, speed, 0.0, 0.0)], state_a, state_b

    planner = _planner_with_arcs(None)
    planner.grid, planner.ceiling, planner._hill = [0.0, 0.5, 1.0], [1.0, 1.0, 1.0], hill
    rows, entry, exit_state = planner._split(1, 0.0, (0.1, 0.0), 1.0, (0.2, 0.0), True, True, 0)
    assert 0.5 - (0.54 - 0.324) / 8.0 <= rows[0][2] <= 0.5
    assert rows[0][2] == rows[1][2]
    assert (entry, exit_state) == ((0.1, 0.0), (0.2, 0.0))
