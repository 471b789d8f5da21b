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

"""What JTC executes: limits on its quintic through FK, honest peaks, the fallbacks."""

import functools
import os
import sys

from ellipath_ros.core.errors import EllipathError
from ellipath_ros.core.joint_trajectory import executed_peaks
from ellipath_ros.core.knots import minimal_knots
from ellipath_ros.core.limits import CartesianLimits
from ellipath_ros.core.planner import _EXECUTED_JERK_SHARE, plan_transfer, PlannerConfig
from ellipath_ros.core.timing import _around, _SAFETY_REFINE, _within_limits, time_motion
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                'scripts'))
import executed_limits  # noqa: E402, I100 (scripts/ is not a package)

PICK = np.array([0.0, 0.0, -0.8])
PLACE = np.array([0.3, 0.0, -0.75])
# Reported peaks may be this much below a finer independent check, no more.
UNDER = 1e-3


def dense_check(trajectory, geometry, step=1e-6, spread=10):
    """
    Return the executed peaks by an independent check at 1/step Hz, as a dict.

    The check of ``scripts/executed_limits.py`` (JTC's quintic through FK at every ``step``,
    central differences ``spread`` samples wide), keyed by the planner's peak names.
    """
    return dict(zip(executed_limits.KEYS,
                    executed_limits.dense_check(trajectory, geometry, step, spread)))


def assert_within_limits(found, config, jerk_share=_EXECUTED_JERK_SHARE):
    limits, joints = config.limits, config.joint_limits
    assert found['peak_speed'] <= limits.max_speed
    assert found['peak_accel'] <= limits.max_accel
    assert found['peak_jerk'] <= jerk_share * limits.max_jerk
    assert found['joint_peak_velocity'] <= joints.max_velocity
    assert found['joint_peak_accel'] <= joints.max_acceleration


def assert_reported_not_below(reported, found):
    for key, value in found.items():
        assert reported[key] >= (1.0 - UNDER) * value, key


@functools.lru_cache(maxsize=None)
def leg_of(join='g2'):
    return plan_transfer(PICK, PLACE, PlannerConfig.from_flat({'join': join}))


def test_executed_peaks_of_the_papers_example_pass_a_1mhz_check():
    config = PlannerConfig()
    leg = leg_of()
    found = dense_check(leg.joint_trajectory, config.geometry)
    assert_within_limits(found, config)
    assert_reported_not_below(leg.executed, found)
    # Not grossly above either (the check's differences smooth the jerk steps at knots).
    for key in ('peak_speed', 'peak_accel', 'joint_peak_velocity', 'joint_peak_accel'):
        assert leg.executed[key] <= 1.01 * found[key], key
    assert executed_peaks(leg.joint_trajectory, config.geometry) == leg.executed


def test_planned_peaks_pass_a_1mhz_check():
    """The planned peaks (metrics) and the in-planner check catch what lies between samples."""
    limits = CartesianLimits()
    leg = leg_of()
    motion = leg.motion
    t = np.arange(0.0, motion.duration, 1e-6)
    _, velocity, acceleration, jerk = motion.state_at(t)
    found = {'peak_speed': np.linalg.norm(velocity, axis=1).max(),
             'peak_accel': np.linalg.norm(acceleration, axis=1).max(),
             'peak_jerk': np.linalg.norm(jerk, axis=1).max()}
    assert_reported_not_below(motion.metrics(), found)
    assert found['peak_speed'] <= limits.max_speed
    assert found['peak_accel'] <= limits.max_accel
    assert found['peak_jerk'] <= limits.max_jerk


def random_pairs(count, seed=14):
    """Seeded pick/place pairs inside the default workspace (unreachable ones are skipped)."""
    rng = np.random.default_rng(seed)
    while True:
        yield (np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3),
                         rng.uniform(-0.95, -0.7)]),
               np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3),
                         rng.uniform(-0.95, -0.7)]))


def test_executed_limits_hold_on_50_random_pairs():
    config = PlannerConfig()
    checked = 0
    for pick, place in random_pairs(50):
        try:
            leg = plan_transfer(pick, place, config)
        except EllipathError:
            continue
        found = dense_check(leg.joint_trajectory, config.geometry, step=2e-6, spread=5)
        assert_within_limits(found, config)
        assert_reported_not_below(leg.executed, found)
        checked += 1
        if checked == 50:
            break


def test_points_are_added_at_the_jerk_steps_where_knots_alone_break_the_jerk():
    config = PlannerConfig()
    leg = leg_of()
    knots, _ = minimal_knots(leg.motion, config.geometry, config.joint_names,
                             config.knot_tolerance)
    bare = executed_peaks(knots, config.geometry)
    # Precondition: the fewest knots within the tolerance break the executed jerk bound.
    assert bare['peak_jerk'] > _EXECUTED_JERK_SHARE * config.limits.max_jerk
    times = leg.joint_trajectory.time_from_start
    assert times.size > knots.time_from_start.size
    # Large jerk steps of the motion got points of their own.
    step_times, sizes = leg.motion.jerk_steps()
    large = step_times[sizes >= config.limits.max_jerk]
    assert (np.abs(times[:, None] - large).min(axis=0) < 1e-9).sum() >= 2


def test_coarse_samples_make_the_leg_slow_down_until_the_executed_limits_hold():
    config = PlannerConfig.from_flat({'output_mode': 'samples', 'sample_period': 0.03})
    leg = plan_transfer(PICK, PLACE, config)
    assert leg.joint_slowdown > 1.0
    found = dense_check(leg.joint_trajectory, config.geometry, step=2e-6, spread=5)
    assert_within_limits(found, config, jerk_share=np.inf)
    assert_reported_not_below(leg.executed, found)


def test_the_papers_join_has_an_unbounded_executed_jerk_which_is_reported():
    config = PlannerConfig.from_flat({'join': 'paper'})
    leg = leg_of('paper')
    found = dense_check(leg.joint_trajectory, config.geometry)
    # The plan steps its acceleration at T1/T2: the quintic turns that into a large jerk.
    assert found['peak_jerk'] > _EXECUTED_JERK_SHARE * config.limits.max_jerk
    assert_reported_not_below(leg.executed, found)
    assert_within_limits(found, config, jerk_share=np.inf)


def test_safety_net_slows_a_motion_down_just_enough():
    """A motion timed for higher limits is brought within lower ones, at 1 MHz."""
    path = leg_of().path
    fast = time_motion(path, CartesianLimits())
    tight = CartesianLimits(max_speed=3.9, max_accel=48.5, max_jerk=4900.0)
    slowed = _within_limits(fast, tight, None)
    assert slowed.time_scale > 1.0
    t = np.arange(0.0, slowed.duration, 1e-6)
    _, velocity, acceleration, jerk = slowed.state_at(t)
    speed = np.linalg.norm(velocity, axis=1).max()
    accel = np.linalg.norm(acceleration, axis=1).max()
    jerk = np.linalg.norm(jerk, axis=1).max()
    assert speed <= tight.max_speed and accel <= tight.max_accel and jerk <= tight.max_jerk
    # Just enough: one of them within 0.5 % of its limit.
    assert max(speed / tight.max_speed, accel / tight.max_accel,
               jerk / tight.max_jerk) > 0.995


def test_safety_net_samples_again_only_next_to_the_marked_samples():
    t = np.array([0.0, 1.0, 3.0, 4.0, 8.0, 9.0])
    close = np.array([False, False, False, False, False, True])
    # The last sample: the one interval before it, _SAFETY_REFINE steps, ends included.
    np.testing.assert_allclose(_around(t, close), np.linspace(8.0, 9.0, _SAFETY_REFINE + 1))
    close = np.array([True, False, True, False, False, False])
    found = _around(t, close)
    expected = np.unique(np.concatenate((np.linspace(0.0, 1.0, _SAFETY_REFINE + 1),
                                         np.linspace(1.0, 3.0, _SAFETY_REFINE + 1),
                                         np.linspace(3.0, 4.0, _SAFETY_REFINE + 1))))
    np.testing.assert_allclose(found, expected)
    assert found.min() == 0.0 and found.max() == 4.0


def test_safety_net_finds_a_peak_between_samples_as_a_dense_check_does():
    """Limits just under the motion's sampled jerk peak: slowed as much as a 1 MHz check asks."""
    fast = time_motion(leg_of().path, CartesianLimits())
    t = np.arange(0.0, fast.duration, 1e-6)
    _, velocity, acceleration, jerk = fast.state_at(t)
    dense_jerk = np.linalg.norm(jerk, axis=1).max()
    # Speed and acceleration far from their limits: only the jerk's peak breaks one.
    tight = CartesianLimits(max_speed=10.0, max_accel=200.0, max_jerk=0.999 * dense_jerk)
    slowed = _within_limits(fast, tight, None)
    needed = (dense_jerk / tight.max_jerk) ** (1.0 / 3.0)
    assert needed <= slowed.time_scale <= needed * (1.0 + 3e-3)
