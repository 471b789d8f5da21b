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

"""The timed motion's default samples: placed by the law's pieces, and the peaks they find."""

import dataclasses

from ellipath_ros.bench.latency import random_pairs
from ellipath_ros.core import motion as motion_module
from ellipath_ros.core.geometry import plan_path
from ellipath_ros.core.planner import _check_reach_and_speed_cap, PlannerConfig
from ellipath_ros.core.timing import time_motion
import numpy as np
import pytest

KINDS = {'g2': {}, 'paper': {'join': 'paper'},
         'curvature': {'join': 'paper', 'profile': 'curvature'}}


def planned_motion(config, pick, place):
    """Return the timed motion of one leg as the planner times it."""
    path = plan_path(pick, place, config.pick_clearance, config.place_clearance, config.arc,
                     config.join, config.join_tolerance)
    return time_motion(path, config.limits, profile=config.profile, r=config.curvature_r,
                       speed_cap=_check_reach_and_speed_cap(path, config))


def piece_times_by_arrays(bounds, counts):
    """Return the times of ``_piece_sample_times`` by the NumPy formulas it was written in."""
    epsilon = 1e-9 * float(bounds[-1])
    starts, widths = bounds[:-1], np.diff(bounds)
    interval = np.repeat(np.arange(starts.size), counts - 1)
    first = np.cumsum(counts - 1) - (counts - 1)
    step = np.arange(interval.size) - first[interval] + 1
    inside = starts[interval] + widths[interval] * (step / counts[interval])
    return np.sort(np.concatenate((inside, bounds[[0, -1]],
                                   np.maximum(bounds[1:-1] - epsilon, 0.0),
                                   np.minimum(bounds[1:-1] + epsilon, bounds[-1]))))


def sequence_state_by_masks(sequence, t):
    """Return ``_Sequence.state`` as a mask per law picks its times (its first formulas)."""
    starts = np.cumsum([0.0] + [law.duration for law in sequence.laws])
    which = np.clip(np.searchsorted(starts, t, side='right') - 1, 0, len(sequence.laws) - 1)
    out = [np.empty_like(t) for _ in range(4)]
    for index, law in enumerate(sequence.laws):
        mask = which == index
        if np.any(mask):
            for target, value in zip(out, law.state(t[mask] - starts[index])):
                target[mask] = value
    return out


def test_refined_peaks_take_a_vertex_between_a_pieces_last_two_samples():
    # Three samples of one piece; the parabola's vertex (value 3) lies between the last two,
    # so the middle sample is no local maximum. A quadratic is found exactly.
    t = np.array([0.0, 1.0, 2.0, 2.0, 3.0, 4.0])
    pieces = np.array([0, 0, 0, 1, 1, 1])
    values = 3.0 - (t - 1.7) ** 2
    # In the second piece the parabola rises past its last sample: no extrapolation.
    values[3:] = 2.0 - (t[3:] - 6.0) ** 2
    norms = np.vstack((values, values, values))
    peaks = np.empty(3)
    motion_module._refined_peaks(t, pieces, norms, peaks)
    np.testing.assert_allclose(peaks, 3.0, rtol=1e-14)
    motion_module._refined_peaks(t[3:].copy(), pieces[3:].copy(), norms[:, 3:].copy(), peaks)
    assert np.all(peaks == values[5])
    plain = np.empty(3)
    motion_module._refined_peaks.py_func(t, pieces, norms, plain)
    motion_module._refined_peaks(t, pieces, norms, peaks)
    assert np.array_equal(plain, peaks)


@pytest.mark.parametrize('join', ['g2', 'paper'])
def test_default_samples_follow_the_pieces_and_the_paths_marks(join):
    path = plan_path((0.1, 0.05, -0.8), (-0.2, 0.1, -0.75), 0.025, 0.02, join=join)
    motion = time_motion(path)
    bounds = motion_module._smooth_bounds(motion)
    t = motion._norm_times(bounds)
    law_bounds = motion.law.times * motion.time_scale
    # Every law bound is a bound; so is every mark of the path (T1, T2, G2 ends).
    assert np.isin(law_bounds, bounds).all()
    marks = motion._mark_times()
    assert np.abs(marks[:, None] - bounds[None, :]).min(axis=1).max() <= 1e-8 * motion.duration
    # Both sides of every interior bound are samples, 1e-9 of the duration off it.
    epsilon = 1e-9 * motion.duration
    for side in (-epsilon, epsilon):
        nearest = np.abs(t[None, :] - (bounds[1:-1, None] + side)).min(axis=1)
        assert nearest.max() <= 1e-6 * epsilon
    # Inside each interval: even steps at most _PIECE_PERIOD apart, at least two.
    interval = np.searchsorted(bounds[1:-1], t, side='right')
    counts = np.bincount(interval, minlength=bounds.size - 1)
    assert counts.min() >= 3
    inside = interval[1:] == interval[:-1]
    assert np.diff(t)[inside].max() <= motion_module._PIECE_PERIOD * (1.0 + 1e-9)
    assert t[0] == 0.0 and t[-1] == motion.duration and np.all(np.diff(t) > 0.0)


@pytest.mark.parametrize('kind', sorted(KINDS))
def test_default_samples_find_the_peaks_of_a_10_us_check(kind):
    config = dataclasses.replace(PlannerConfig(), **KINDS[kind])
    for pick, place in random_pairs(4, seed=5):
        motion = planned_motion(config, pick, place)
        metrics = motion.metrics()
        law = motion.law
        bounds = (law.times if hasattr(law, 'times') else law.bounds()[0]) * motion.time_scale
        epsilon = 1e-9 * motion.duration
        t = np.unique(np.concatenate((
            np.linspace(0.0, motion.duration, int(motion.duration / 1e-5) + 1),
            np.clip(np.concatenate((bounds - epsilon, bounds + epsilon)), 0.0,
                    motion.duration))))
        _, velocity, acceleration, jerk = motion.state_at(t)
        for key, vectors in (('peak_speed', velocity), ('peak_accel', acceleration),
                             ('peak_jerk', jerk)):
            dense = float(np.linalg.norm(vectors, axis=1).max())
            assert dense * (1.0 - 2e-4) <= metrics[key] <= dense * (1.0 + 2e-4), key


@pytest.mark.parametrize('join', ['g2', 'paper'])
def test_compiled_default_samples_equal_the_array_formulas_bit_for_bit(join):
    # The times of _piece_sample_times with ceil(width / period) steps per interval, the law's
    # state as path_state gives it and each sample's interval as np.searchsorted finds it;
    # also slowed down (path_state divides by the factor and its powers).
    config = dataclasses.replace(PlannerConfig(), join=join)
    for pick, place in random_pairs(6, seed=9):
        timed = planned_motion(config, pick, place)
        for factor in (1.0, 1.0123456789, 1.37):
            motion = dataclasses.replace(timed.scaled(factor) if factor > 1.0 else timed)
            bounds = motion_module._smooth_bounds(motion)
            t = motion._norm_times(bounds)
            period = max(motion_module._PIECE_PERIOD,
                         motion.duration / motion_module._METRICS_SAMPLES)
            counts = np.maximum(np.ceil(np.diff(bounds) / period), 2.0).astype(np.int64)
            expected = np.minimum(piece_times_by_arrays(bounds, counts), motion.duration)
            assert np.array_equal(t, expected)
            s, states, norms, peaks = motion_module._sampled(motion, t, bounds)
            path_s, velocity, acceleration, jerk = motion.path_state(t)
            assert np.array_equal(s, path_s)
            assert all(np.array_equal(mine, theirs) for mine, theirs in zip(
                states, motion.state_at(t)))
            pieces = np.empty(t.size, np.int64)
            rows = np.empty((4, t.size))
            law = motion.law
            motion_module._sorted_law_rows(
                t, motion.duration, motion.time_scale, motion.time_scale ** 2,
                motion.time_scale ** 3, law.times, law.s0, law.v0, law.a0, law.jerk,
                bounds[1:-1].copy(), rows, pieces)
            assert np.array_equal(pieces, np.searchsorted(bounds[1:-1], t, side='right'))
            assert np.array_equal(rows, np.vstack((path_s, velocity, acceleration, jerk)))


def test_curvature_samples_and_states_equal_the_array_formulas_bit_for_bit():
    # The sequence of laws of the curvature profile: each law's sample times, as the NumPy
    # formulas give them, and its states at sorted, unsorted and repeated times, as a mask
    # per law picks them; the bounds, kept once, are read-only.
    config = dataclasses.replace(PlannerConfig(), **KINDS['curvature'])
    rng = np.random.default_rng(3)
    for pick, place in random_pairs(6, seed=9):
        sequence = planned_motion(config, pick, place).law
        assert isinstance(sequence, motion_module._Sequence)
        for law in sequence.laws:
            bounds = getattr(law, 'times', None)
            if bounds is None:
                bounds = law._hermite_table[0]
            counts = np.full(bounds.size - 1, motion_module._PIECE_SAMPLES)
            assert np.array_equal(law.sample_times(motion_module._PIECE_SAMPLES),
                                  piece_times_by_arrays(bounds, counts))
        times = sequence.bounds()[0]
        assert not times.flags.writeable
        duration = sequence.duration
        for t in (np.sort(rng.uniform(0.0, duration, 500)), rng.uniform(0.0, duration, 500),
                  np.concatenate((times - 1e-9 * duration, times + 1e-9 * duration)),
                  np.array(sequence._starts), np.array([duration]),
                  np.array([0.0, 0.0, duration, 0.5 * duration])):
            expected = sequence_state_by_masks(sequence, t)
            assert all(np.array_equal(mine, theirs) for mine, theirs in zip(
                sequence.state(t), expected))
