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

"""Approach legs planned ahead: the plan with one, the start prediction and the cache."""

from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import WorkspaceError
from ellipath_ros.core.planner import plan_approach
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.preplanning import ApproachCache
from ellipath_ros.core.sequencing import PosePairing
from ellipath_ros.core.sequencing import Sequencer
import numpy as np
import pytest

from test_sequencing import FakeClock
from test_sequencing import motion_of

CONFIG = PlannerConfig()
START = np.array([0.12, -0.05, -0.78])
PICK = np.array([-0.15, 0.10, -0.85])
PLACE = np.array([0.20, 0.12, -0.80])
HOME = np.array([0.0, 0.0, -0.8])
TOLERANCE = 1e-3


def assert_same_trajectory(first, second):
    """Assert two CyclePlans publish the same points, bit for bit."""
    for name in ('time_from_start', 'positions', 'velocities', 'accelerations'):
        assert np.array_equal(getattr(first.joint_trajectory, name),
                              getattr(second.joint_trajectory, name)), name


# --- the plan with an approach planned ahead ----------------------------------------------

@pytest.mark.parametrize('config, start, dwells', [
    (CONFIG, START, (0.0, 0.0)),
    (CONFIG, START, (0.15, 0.05)),
    (PlannerConfig(output_mode='samples'), START, (0.0, 0.1)),
    (PlannerConfig(profile='curvature', join='paper'), HOME, (0.0, 0.0)),
    (CONFIG, PICK, (0.1, 0.0)),  # the robot on the pick: no approach leg
])
def test_a_cycle_with_its_approach_planned_ahead_is_the_cycle_planned_in_one_go(
        config, start, dwells):
    whole = plan_cycle(start, PICK, PLACE, config, *dwells)
    approach = plan_approach(start, PICK, config)
    assert (approach.leg is None) == (len(whole.legs) == 1)
    reused = plan_cycle(start, PICK, PLACE, config, *dwells, approach=approach)
    assert_same_trajectory(whole, reused)
    assert len(reused.legs) == len(whole.legs)
    if approach.leg is not None:
        assert reused.legs[0] is approach.leg
        assert whole.metrics['approach.preplanned'] == 'false'
        assert reused.metrics['approach.preplanned'] == 'true'
        assert reused.metrics['approach.plan_time'] == approach.plan_time
        assert reused.metrics['duration'] == whole.metrics['duration']
    assert reused.metrics['plan_time'] > 0.0


def test_an_approach_within_the_tolerance_is_used_from_its_own_start():
    approach = plan_approach(START, PICK, CONFIG)
    nearby = START + [0.0006, 0.0, 0.0]
    cycle = plan_cycle(nearby, PICK, PLACE, CONFIG, approach=approach,
                       start_tolerance=TOLERANCE)
    assert_same_trajectory(cycle, plan_cycle(START, PICK, PLACE, CONFIG))


@pytest.mark.parametrize('change, tolerance, message', [
    ({'start': START + [0.002, 0.0, 0.0]}, TOLERANCE,
     r'expected a leg from within 0\.001 m of the start .*, got one from \[0\.12'),
    ({'start': START + [1e-9, 0.0, 0.0]}, 0.0, 'expected a leg from within 0 m'),
    ({'pick': PICK + [0.0, 1e-12, 0.0]}, TOLERANCE, r'expected a leg to the pick .*, got one to'),
    ({'config': PlannerConfig.from_flat({'max_speed': 3.0})}, TOLERANCE,
     r'expected a leg planned with the configuration .*max_speed=3\.0.*, got one planned with '
     r'.*max_speed=4\.0'),
])
def test_an_approach_for_another_cycle_is_refused_naming_the_mismatch(
        change, tolerance, message):
    approach = plan_approach(START, PICK, CONFIG)
    request = {'start': START, 'pick': PICK, 'config': CONFIG, **change}
    with pytest.raises(InvalidInputError, match=message):
        plan_cycle(request['start'], request['pick'], PLACE, request['config'],
                   approach=approach, start_tolerance=tolerance)


def test_an_equal_configuration_built_anew_is_the_same_configuration():
    approach = plan_approach(START, PICK, PlannerConfig.from_flat({'max_speed': 3.0}))
    cycle = plan_cycle(START, PICK, PLACE, PlannerConfig.from_flat({'max_speed': 3.0}),
                       approach=approach)
    assert cycle.metrics['approach.preplanned'] == 'true'


def test_the_approach_is_checked_as_in_the_cycle():
    outside = np.array([0.0, 0.0, -0.5])  # above workspace_z_max
    with pytest.raises(WorkspaceError, match='start'):
        plan_approach(outside, PICK, CONFIG)
    with pytest.raises(WorkspaceError, match='start'):
        plan_cycle(outside, PICK, PLACE, CONFIG)
    with pytest.raises(InvalidInputError, match='start'):
        plan_approach([0.0, float('nan'), -0.8], PICK, CONFIG)


# --- where the next pair starts -------------------------------------------------------------

def test_the_predicted_start_is_the_last_place_queued_else_the_motions_end_else_none():
    clock = FakeClock()
    sequencer = Sequencer(6, clock=clock)
    assert sequencer.predicted_start() is None, 'idle: the robot at rest'
    first = sequencer.submit(PICK, PLACE, 'place_pose')
    second_place = PLACE + [0.0, -0.2, 0.0]
    sequencer.submit(PICK, second_place, 'place_pose')
    assert np.array_equal(sequencer.predicted_start(), second_place), 'waiting'
    request, start = sequencer.take_for_planning()
    assert request is first and start is None
    assert np.array_equal(sequencer.predicted_start(), second_place)
    sequencer.plan_finished(motion_of(request, HOME))
    request, start = sequencer.take_for_planning()
    assert np.array_equal(start, PLACE), 'the held motion ends at its place'
    assert np.array_equal(sequencer.predicted_start(), second_place), 'being planned'
    sequencer.plan_finished(motion_of(request, start))
    assert np.array_equal(sequencer.predicted_start(), second_place), 'held'
    sequencer.released(sequencer.take_for_release(), clock.now)
    assert np.array_equal(sequencer.predicted_start(), second_place), 'one still held'
    taken = sequencer.take_for_release(clock.now + 1.0)
    assert np.array_equal(sequencer.predicted_start(), second_place), 'being released'
    sequencer.released(taken, clock.now + 1.0)
    clock.now += 1.2
    assert np.array_equal(sequencer.predicted_start(), second_place), 'running'
    # What take_for_planning gives the next pair is what was predicted for it.
    third = sequencer.submit(PICK, HOME, 'place_pose')
    request, start = sequencer.take_for_planning()
    assert request is third and np.array_equal(start, second_place)
    sequencer.plan_failed('unreachable')
    clock.now += 1.0  # the last motion has ended
    assert sequencer.predicted_start() is None


def test_the_planning_wait_returns_early_when_told():
    sequencer = Sequencer(2)
    assert sequencer.next_to_plan(0.0, until=lambda: True) is None
    sequencer.wake()  # nobody waits: nothing happens
    assert sequencer.next_to_plan(0.01, until=lambda: False) is None
    sequencer.submit(PICK, PLACE, 'place_pose')
    request, _ = sequencer.next_to_plan(0.01, until=lambda: True)
    assert request.number == 1, 'a waiting pair comes first'


# --- the cache ------------------------------------------------------------------------------

class Settings:
    """A settings token (compared by identity)."""


def preplan(cache, start, token):
    """Plan every pick the cache wants from ``start``, as the node does; return their count."""
    count = 0
    while (wanted := cache.next_to_plan(start, TOLERANCE, token)) is not None:
        slot, pick = wanted
        cache.store(slot, start, token, plan_approach(start, pick, CONFIG))
        count += 1
    return count


def test_a_pick_planned_ahead_and_paired_is_taken_by_its_pair():
    cache, token = ApproachCache(4), Settings()
    assert not cache.wanted()
    cache.add((1, 0), PICK)
    assert cache.wanted() and cache.waiting_picks == 1
    assert preplan(cache, START, token) == 1 and not cache.wanted()
    assert preplan(cache, START + [TOLERANCE / 2, 0.0, 0.0], token) == 0, 'still fits'
    cache.claim((1, 0), 7)
    assert cache.waiting_picks == 0 and len(cache) == 1
    assert preplan(cache, HOME, token) == 0, 'claimed: no longer planned'
    approach = cache.take(7, PICK, START, TOLERANCE, token)
    assert approach is not None and np.array_equal(approach.start, START)
    assert cache.take(7, PICK, START, TOLERANCE, token) is None, 'taken once'
    assert cache.counts() == {'legs': 1, 'hits': 1, 'misses': 1}
    assert len(cache) == 0


@pytest.mark.parametrize('pick, start, other_token', [
    (PICK + [1e-9, 0.0, 0.0], START, False),
    (PICK, START + [2 * TOLERANCE, 0.0, 0.0], False),
    (PICK, START, True),
])
def test_an_approach_for_another_pick_start_or_settings_is_a_miss(pick, start, other_token):
    cache, token = ApproachCache(4), Settings()
    cache.add(None, PICK)
    preplan(cache, START, token)
    cache.claim(None, 1)
    assert cache.take(1, pick, start, TOLERANCE, Settings() if other_token else token) is None
    assert cache.counts() == {'legs': 1, 'hits': 0, 'misses': 1}


def test_a_start_no_longer_predicted_or_new_settings_are_planned_again():
    cache, token = ApproachCache(4), Settings()
    cache.add('a', PICK)
    preplan(cache, START, token)
    assert preplan(cache, PLACE, token) == 1, 'another pair queued ahead: its place'
    new_token = Settings()
    assert preplan(cache, PLACE, new_token) == 1, 'a parameter change'
    cache.claim('a', 3)
    assert cache.take(3, PICK, PLACE, TOLERANCE, new_token).start.tolist() == PLACE.tolist()


def test_a_leg_that_comes_after_its_place_is_still_used():
    cache, token = ApproachCache(4), Settings()
    cache.add('a', PICK)
    slot, pick = cache.next_to_plan(START, TOLERANCE, token)
    cache.claim('a', 1)  # the place arrives while the leg is planned
    cache.store(slot, START, token, plan_approach(START, pick, CONFIG))
    assert cache.take(1, PICK, START, TOLERANCE, token) is not None


def test_a_failed_leg_is_not_planned_again_from_the_same_start_and_is_a_miss():
    cache, token = ApproachCache(4), Settings()
    cache.add('a', PICK)
    slot, _ = cache.next_to_plan(START, TOLERANCE, token)
    cache.store(slot, START, token, None)
    assert cache.next_to_plan(START, TOLERANCE, token) is None and not cache.wanted()
    cache.claim('a', 1)
    assert cache.take(1, PICK, START, TOLERANCE, token) is None
    assert cache.counts() == {'legs': 1, 'hits': 0, 'misses': 1}


def test_picks_replaced_dropped_cleared_or_beyond_the_bound_lose_their_leg():
    cache, token = ApproachCache(2), Settings()
    cache.add('a', PICK)
    preplan(cache, START, token)
    cache.add('a', PICK + [0.01, 0.0, 0.0])  # replaced: planned again, for the new pick
    assert cache.wanted() and preplan(cache, START, token) == 1
    cache.add('b', PICK)
    cache.add('c', PICK)  # beyond the bound: the oldest ('a') goes
    cache.claim('a', 1)
    assert cache.take(1, PICK + [0.01, 0.0, 0.0], START, TOLERANCE, token) is None
    cache.discard('b')  # evicted or cleared by the pairing
    cache.claim('b', 2)
    cache.claim('c', None)  # its pair rejected
    assert len(cache) == 0
    cache.add('d', PICK)
    preplan(cache, START, token)
    cache.claim('d', 4)
    cache.add('e', PICK)
    cache.clear()  # parameters changed, queue cleared, belt moving
    assert len(cache) == 0 and not cache.wanted()
    assert cache.take(4, PICK, START, TOLERANCE, token) is None
    assert cache.counts() == {'legs': 3, 'hits': 0, 'misses': 2}
    with pytest.raises(InvalidInputError, match='depth'):
        ApproachCache(0)


def test_the_pairing_names_the_keys_of_the_picks_it_drops():
    pairing = PosePairing()
    pairing.add_pick((1, 0), PICK, 'stamp', depth=2)
    pairing.add_pick((1, 0), PICK, 'stamp', depth=2)  # replaced
    pairing.add_pick((2, 0), PICK, 'stamp', depth=2)
    pairing.add_pick((3, 0), PICK, 'stamp', depth=2)  # evicts (1, 0)
    assert pairing.take_dropped_keys() == [(1, 0), (1, 0)]
    pairing.add_pick(None, PICK, 'sequence', depth=2)  # the mode changes: every pick cleared
    assert pairing.take_dropped_keys() == [(2, 0), (3, 0)]
    assert pairing.take_dropped_keys() == []
    assert PosePairing.key((5, 0), 'sequence') is None
    assert PosePairing.key((5, 0), 'stamp') == (5, 0)
