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

"""Points that split knot segments (a knot round): where they go, and what they are checked."""

from ellipath_ros.core import knots as knot_search
from ellipath_ros.core import planner
from ellipath_ros.core.joint_trajectory import _SAFETY
from ellipath_ros.core.joint_trajectory import _SAME_TIME
from ellipath_ros.core.joint_trajectory import MotionSamples
from ellipath_ros.core.knots import minimal_knots
from ellipath_ros.core.knots import segment_deviations
from ellipath_ros.core.planner import PlannerConfig
import numpy as np
import pytest
from test_knot_search import LEGS as KNOT_SEARCH_LEGS

CONFIG = PlannerConfig()
GAP = planner._KNOT_MIN_GAP
# The curvature profile's samples are 4 per law piece: most points added there are at times
# no sample gives, so the split stops for the motion's states and runs again.
LEGS = {kind: motions[:8] for kind, motions in KNOT_SEARCH_LEGS.items()}


@pytest.mark.parametrize('seed', range(20))
def test_added_points_keep_their_distance_from_the_points_and_each_other(seed):
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.5 * GAP, 20 * GAP, 30))
    # Candidates near the points, near each other, repeated, in any order.
    added = np.concatenate((times[rng.integers(0, 30, 10)] + rng.uniform(-GAP, GAP, 10),
                            rng.uniform(times[0], times[-1], 30)))
    added = np.concatenate((added, added[:5]))
    rng.shuffle(added)
    kept = knot_search._spaced(times, added, GAP)
    assert kept.dtype == float and np.all(np.diff(kept) >= GAP)
    assert np.isin(kept, added).all()
    assert np.abs(kept[:, None] - times[None, :]).min(initial=np.inf) >= GAP
    # Each candidate left out is too close to a point, or to one kept before it (in time order).
    for candidate in np.setdiff1d(added, kept):
        near_point = np.abs(times - candidate).min() < GAP
        earlier = kept[kept < candidate]
        assert near_point or (earlier.size and candidate - earlier[-1] < GAP)


@pytest.mark.parametrize('tolerance', [1e-4, 5e-6])
@pytest.mark.parametrize('kind', sorted(LEGS))
def test_split_points_are_the_motions_states_and_their_segments_are_checked(kind, tolerance):
    # Below 1e-5 m the checks evaluate the motion itself (the split stops for it).
    splits = 0
    for motion in LEGS[kind]:
        samples = MotionSamples.of(motion, CONFIG.geometry)
        trajectory = minimal_knots(motion, CONFIG.geometry, tolerance=tolerance,
                                   samples=samples)[0]
        times = trajectory.time_from_start
        steps = np.sort(motion.jerk_steps()[0])
        segments = np.arange(0, times.size - 1, 2)
        for halvings in (0, planner._MEND_HALVINGS):
            split, deviation = knot_search._split_segments(samples, trajectory, steps, segments,
                                                           tolerance, GAP, halvings)
            new_times = split.time_from_start
            assert np.all(np.diff(new_times) > 0.0)
            kept = np.isin(new_times, times)
            # The points stay, each with its state.
            assert kept.sum() == times.size
            for name in ('positions', 'velocities', 'accelerations'):
                np.testing.assert_array_equal(getattr(split, name)[kept],
                                              getattr(trajectory, name))
            added = new_times[~kept]
            assert added.size > 0
            splits += 1
            # Inside the segments split, away from the points and each other.
            inside = np.searchsorted(times, added) - 1
            assert np.isin(inside, segments).all()
            assert np.abs(added[:, None] - times[None, :]).min() >= GAP
            assert np.diff(added).min(initial=np.inf) >= GAP
            # Each on the sample at its time, or at the motion's state there.
            states = samples.states(added)
            np.testing.assert_array_equal(states[0], added)
            for values, name in zip(states[1:], ('positions', 'velocities', 'accelerations')):
                np.testing.assert_array_equal(getattr(split, name)[~kept], values)
            # The deviation is that of the segments with a new end, as the knots' are checked.
            made = np.flatnonzero(~(kept[:-1] & kept[1:]))
            deviations = segment_deviations(samples, split, made, tolerance)
            if (deviations <= _SAFETY * tolerance).all():
                assert deviation == deviations.max()
            else:
                assert deviation == np.inf
            if halvings == 0:
                # Without halvings: the steps inside a segment split it, else its middle.
                for segment in segments:
                    start, end = times[segment], times[segment + 1]
                    within = added[(added > start) & (added < end)]
                    stepped = steps[(steps > start + GAP) & (steps < end - GAP)]
                    if stepped.size:
                        # At a step, or on the sample at its time.
                        off = np.abs(within[:, None] - stepped[None, :]).min(axis=1)
                        assert (off <= _SAME_TIME * motion.duration).all()
                    else:
                        middle = 0.5 * (start + end)
                        assert within.size == 1
                        assert abs(within[0] - middle) <= 0.25 * (end - start)
    assert splits == 2 * len(LEGS[kind])
