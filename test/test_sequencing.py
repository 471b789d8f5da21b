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

"""The cycle queue, the release timing, the start check and the pairing, without ROS."""

import threading
import time

from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import quintic_interpolate
from ellipath_ros.core.kinematics import forward_kinematics
from ellipath_ros.core.kinematics import inverse_kinematics
from ellipath_ros.core.planner import plan_cycle
from ellipath_ros.core.planner import PlannerConfig
from ellipath_ros.core.sequencing import check_start
from ellipath_ros.core.sequencing import PlannedMotion
from ellipath_ros.core.sequencing import PosePairing
from ellipath_ros.core.sequencing import QueueFullError
from ellipath_ros.core.sequencing import release_timing
from ellipath_ros.core.sequencing import Sequencer
from ellipath_ros.core.sequencing import track_deviation
from ellipath_ros.core.sequencing import UnpairedPlaceError
import numpy as np
import pytest

CONFIG = PlannerConfig()
HOME = np.array([0.0, 0.0, -0.8])
PICK = np.array([0.10, 0.05, -0.85])
PLACE = np.array([-0.15, -0.10, -0.82])
PERIOD = 0.002


class FakeClock:
    """A clock that moves only when told."""

    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def motion_of(request, start, duration=0.5):
    """Return a PlannedMotion of ``request``: two points from ``start`` to its place."""
    trajectory = JointTrajectoryData(
        ('joint_1', 'joint_2', 'joint_3'), [0.0, duration],
        inverse_kinematics(np.array([start, request.place]), CONFIG.geometry),
        np.zeros((2, 3)), np.zeros((2, 3)))
    return PlannedMotion(request, trajectory, np.asarray(start, dtype=float), request.place,
                         plan_time=0.01)


def added_up(counts):
    """Return whether every pair received is accounted for exactly once, each kind too."""
    by_kind = {outcome: sum(count for name, count in counts.items()
                            if name.startswith(f'{outcome}_'))
               for outcome in ('rejected', 'dropped')}
    return (counts['received'] == (counts['released'] + counts['rejected'] + counts['dropped']
                                   + counts['queued'] + counts['releasing'])
            and by_kind == {'rejected': counts['rejected'], 'dropped': counts['dropped']})


@pytest.fixture
def clock():
    return FakeClock()


@pytest.fixture
def sequencer(clock):
    return Sequencer(3, clock=clock)


def plan_next(sequencer, duration=0.5):
    """Plan the oldest waiting pair the way the node does; return (request, start)."""
    request, start = sequencer.take_for_planning()
    begin = HOME if start is None else start
    assert sequencer.plan_finished(motion_of(request, begin, duration))
    return request, start


# --- pairing -----------------------------------------------------------------------------

def pick_ledger_adds_up(counts):
    """Return True if every pick counted as received ended in exactly one outcome."""
    return counts['received'] == sum(counts[name] for name in (
        'paired', 'pending', 'invalid', 'replaced', 'evicted', 'cleared'))


def test_stamp_pairing_pairs_identical_stamps_and_never_another_pick():
    pairing = PosePairing()
    pairing.add_pick((1, 0), 'a', 'stamp', 10)
    pairing.add_pick((2, 0), 'b', 'stamp', 10)
    assert pairing.take_notices() == []
    # The place of stamp 1 was lost: the place of stamp 2 still gets pick b.
    assert pairing.take_pick((2, 0), 'stamp') == 'b'
    with pytest.raises(UnpairedPlaceError, match='stamp'):
        pairing.take_pick((3, 0), 'stamp')
    assert len(pairing) == 1
    pairing.add_pick((4, 0), 'c', 'stamp', 1)
    [(kind, text)] = pairing.take_notices()
    assert kind == 'pick_evicted' and 'queue full' in text and '(1, 0)' in text
    with pytest.raises(UnpairedPlaceError):
        pairing.take_pick((1, 0), 'stamp')  # evicted, with a notice, when the queue was full
    assert pairing.take_pick((4, 0), 'stamp') == 'c'
    counts = pairing.counts()
    assert (counts['received'], counts['paired'], counts['evicted'], counts['pending']) == (
        3, 2, 1, 0)
    assert pick_ledger_adds_up(counts)


def test_a_place_read_before_its_pick_waits_for_it_and_joins_no_other():
    pairing = PosePairing()
    pairing.add_pick((1, 0), 'a', 'stamp', 10)
    # The place of stamp 2 is read before its pick: it waits instead of being rejected.
    assert pairing.take_pick((2, 0), 'stamp', wait=0.5, depth=10) is None
    pairing.hold_place((2, 0), 'place 2', now=10.0, wait=0.5)
    assert pairing.waiting_places == 1 and len(pairing) == 1
    assert pairing.expired_places(10.4) == []
    # Pick 3 does not take place 2; pick 2 does, and is counted paired.
    assert pairing.add_pick((3, 0), 'c', 'stamp', 10) is None
    assert pairing.add_pick((2, 0), 'b', 'stamp', 10) == 'place 2'
    assert pairing.waiting_places == 0 and len(pairing) == 2
    assert pairing.take_pick((1, 0), 'stamp') == 'a'
    counts = pairing.counts()
    assert (counts['received'], counts['paired'], counts['pending']) == (3, 2, 1)
    assert pick_ledger_adds_up(counts)


def test_a_waiting_place_expires_as_unpaired_and_waiting_is_bounded():
    pairing = PosePairing()
    assert pairing.take_pick((5, 0), 'stamp', wait=0.5, depth=1) is None
    pairing.hold_place((5, 0), 'place 5', now=1.0, wait=0.5)
    # No room for a second waiting place, and no waiting without ``wait``: unpaired at once.
    with pytest.raises(UnpairedPlaceError, match=r'stamp \(6, 0\)'):
        pairing.take_pick((6, 0), 'stamp', wait=0.5, depth=1)
    with pytest.raises(UnpairedPlaceError):
        pairing.take_pick((7, 0), 'stamp')
    assert pairing.expired_places(1.499) == []
    [error] = pairing.expired_places(1.5)
    assert isinstance(error, UnpairedPlaceError) and error.kind == 'unpaired'
    assert '(5, 0)' in str(error) and '0.5 s' in str(error)
    assert pairing.waiting_places == 0 and pairing.expired_places(9.0) == []
    # Its pick, late, waits as a pick (evicted in time), never joined with another place.
    assert pairing.add_pick((5, 0), 'late', 'stamp', 10) is None
    assert len(pairing) == 1


def test_sequence_pairing_never_holds_a_place_and_a_mode_change_expires_waiting_ones():
    pairing = PosePairing()
    with pytest.raises(UnpairedPlaceError, match='pending'):
        pairing.take_pick((1, 0), 'sequence', wait=0.5, depth=10)
    assert pairing.take_pick((2, 0), 'stamp', wait=0.5, depth=10) is None
    pairing.hold_place((2, 0), 'place 2', now=0.0, wait=0.5)
    # A second place of the same stamp replaces the first, which expires at once.
    pairing.hold_place((2, 0), 'place 2 again', now=0.1, wait=0.5)
    assert pairing.waiting_places == 2  # the replaced one is still to be answered
    [replaced] = pairing.expired_places(0.1)
    assert 'second' in str(replaced) and '(2, 0)' in str(replaced)
    assert pairing.add_pick((2, 0), 'b', 'sequence', 10) is None
    [cleared] = pairing.expired_places(0.2)
    assert 'stamp to sequence' in str(cleared) and pairing.waiting_places == 0
    assert pairing.take_pick((9, 0), 'sequence') == 'b'


def test_sequence_pairing_takes_the_pending_pick_and_a_mode_change_clears():
    pairing = PosePairing()
    pairing.add_pick((1, 0), 'a', 'sequence', 10)
    pairing.add_pick((2, 0), 'b', 'sequence', 10)
    assert [kind for kind, _ in pairing.take_notices()] == ['pick_replaced']
    assert pairing.take_pick((9, 0), 'sequence') == 'b'
    with pytest.raises(UnpairedPlaceError, match='pending'):
        pairing.take_pick((9, 0), 'sequence')
    pairing.add_pick((1, 0), 'a', 'sequence', 10)
    pairing.add_pick((1, 0), 'x', 'stamp', 10)  # the sequence pick is dropped, with a notice
    [(kind, text)] = pairing.take_notices()
    assert kind == 'pick_cleared' and 'sequence to stamp' in text
    assert len(pairing) == 1 and pairing.take_pick((1, 0), 'stamp') == 'x'
    pairing.reject_pick()
    counts = pairing.counts()
    assert (counts['replaced'], counts['cleared'], counts['invalid'], counts['paired']) == (
        1, 1, 1, 2)
    assert pick_ledger_adds_up(counts)


# --- the queue ---------------------------------------------------------------------------

def test_a_full_queue_rejects_the_newest_pair_naming_the_length(sequencer):
    for _ in range(3):
        sequencer.submit(PICK, PLACE, 'pick_place')
    with pytest.raises(QueueFullError, match='3 pairs queued') as error:
        sequencer.submit(PICK, PLACE, 'pick_place')
    assert 'pair 4' in str(error.value) and error.value.kind == 'queue_full'
    counts = sequencer.counts()
    assert (counts['received'], counts['rejected'], counts['queued']) == (4, 1, 3)
    assert added_up(counts)
    # Planned and held pairs count too: one planned, still 3 in the queue.
    plan_next(sequencer)
    with pytest.raises(QueueFullError):
        sequencer.submit(PICK, PLACE, 'pick_place')


def test_a_pair_rejected_before_the_queue_is_counted_and_numbered(sequencer):
    sequencer.submit(PICK, PLACE, 'pick_place')
    assert sequencer.reject() == 2
    assert sequencer.submit(PICK, PLACE, 'pick_place').number == 3
    counts = sequencer.counts()
    assert (counts['received'], counts['rejected'], counts['queued']) == (3, 1, 2)
    assert added_up(counts)


def test_pairs_are_planned_in_order_each_from_the_end_of_the_one_before(sequencer, clock):
    places = [PLACE, PICK, np.array([0.0, -0.2, -0.8])]
    numbers = [sequencer.submit(PICK, place, 'place_pose').number for place in places]
    assert numbers == [1, 2, 3]
    first, start = plan_next(sequencer)
    assert first.number == 1 and start is None, 'nothing runs: the caller finds the robot'
    second, start = plan_next(sequencer)
    assert second.number == 2 and np.array_equal(start, places[0])
    # The first is released and runs; the third is planned from the held second's end.
    motion = sequencer.take_for_release()
    sequencer.released(motion, clock.now)
    third, start = plan_next(sequencer)
    assert third.number == 3 and np.array_equal(start, places[1])
    assert sequencer.take_for_planning() is None


def test_belt_pairs_are_planned_in_latch_order_each_accounted_for(clock):
    # Two cameras: pairs arrive out of latch order. Arrival order stays the default.
    latches = [5.2, 5.0, 5.3, 5.0, None]
    for by_latch, expected in ((False, [1, 2, 3, 4, 5]), (True, [5, 2, 4, 1, 3])):
        sequencer = Sequencer(8, clock=clock)
        for latch in latches:
            sequencer.submit(PICK, PLACE, 'pick_place', latch)
        taken = []
        for index in range(len(latches)):
            request, _ = sequencer.take_for_planning(by_latch=by_latch)
            taken.append(request.number)
            if index == 1:
                # Missed by its plan: rejected with its kind, never silently dropped.
                sequencer.plan_failed('missed')
            else:
                sequencer.plan_finished(motion_of(request, HOME))
        assert taken == expected
        assert sequencer.take_for_planning(by_latch=by_latch) is None
        counts = sequencer.counts()
        assert counts['rejected_missed'] == 1 and counts['held'] == 4 and added_up(counts)


def test_held_motions_from_the_first_stale_one_are_planned_again_in_their_order(clock):
    sequencer = Sequencer(6, clock=clock)
    for _ in range(5):
        sequencer.submit(PICK, PLACE, 'pick_place', 1.0)
    for _ in range(4):
        plan_next(sequencer)
    assert sequencer.requeue_held(lambda motion: False) == []
    # Pair 2 is stale: 3 and 4, planned from its end, go back with it, before pair 5.
    assert sequencer.requeue_held(lambda motion: motion.request.number == 2) == [2, 3, 4]
    counts = sequencer.counts()
    assert counts['held'] == 1 and counts['planned'] == 1 and added_up(counts)
    taken = []
    while True:
        taken_now = sequencer.take_for_planning()
        if taken_now is None:
            break
        request, start = taken_now
        # Each planned again from the end of the motion held before it.
        assert np.array_equal(start, PLACE)
        sequencer.plan_finished(motion_of(request, start))
        taken.append(request.number)
    assert taken == [2, 3, 4, 5]
    counts = sequencer.counts()
    assert counts['planned'] == 5 and counts['held'] == 5 and added_up(counts)


def test_the_tail_is_the_running_motion_while_it_runs_and_the_robot_after(sequencer, clock):
    sequencer.submit(PICK, PLACE, 'place_pose')
    plan_next(sequencer, duration=0.5)
    sequencer.released(sequencer.take_for_release(), clock.now)
    sequencer.submit(PICK, PICK + [0.1, 0.0, 0.0], 'place_pose')
    clock.now += 0.3
    request, start = sequencer.take_for_planning()
    assert np.array_equal(start, PLACE), 'the running motion ends at the place'
    sequencer.plan_failed('unreachable')
    sequencer.submit(PICK, PLACE, 'place_pose')
    clock.now += 0.3  # the first motion has ended
    request, start = sequencer.take_for_planning()
    assert start is None
    counts = sequencer.counts()
    assert (counts['rejected'], counts['planned'], counts['released']) == (1, 1, 1)
    assert counts['rejected_unreachable'] == 1 and added_up(counts)


@pytest.mark.parametrize('header_stamp', ['zero', 'ahead'])
def test_a_held_motion_is_released_only_when_the_one_before_has_ended(clock, header_stamp):
    sequencer = Sequencer(5, clock=clock)
    for _ in range(3):
        sequencer.submit(PICK, PLACE, 'pick_place')
        plan_next(sequencer, duration=0.4)
    releases = []
    for _ in range(3):
        due = sequencer.due(clock.now)
        if releases:
            assert due == pytest.approx(releases[-1].latest_end)
            clock.now = due - 1e-6
            assert sequencer.take_for_release() is None, 'never while the previous one runs'
            clock.now = due
        motion = sequencer.take_for_release()
        assert motion is not None and sequencer.take_for_release() is None
        releases.append(sequencer.released(motion, clock.now, header_stamp, PERIOD, 0.004))
    first, second, _ = releases
    if header_stamp == 'zero':
        assert second.published == pytest.approx(first.published + PERIOD + 0.4)
        assert (second.earliest_start, second.latest_start) == pytest.approx(
            (second.published, second.published + PERIOD))
        assert second.predicted_gap() == pytest.approx((0.0, 2 * PERIOD))
    else:
        assert second.stamp == second.earliest_start == second.latest_start
        assert second.stamp == pytest.approx(second.published + 0.004)
        assert second.predicted_gap() == pytest.approx((0.004, 0.004))
    assert first.predicted_gap() is None and second.release_delay() == pytest.approx(0.0)
    assert not second.waited_for_planner
    assert sequencer.predicted_end(clock.now) == pytest.approx(releases[-1].latest_end)
    assert sequencer.running(releases[-1].latest_end - 1e-6) is releases[-1]
    assert sequencer.running(releases[-1].latest_end) is None
    counts = sequencer.counts()
    assert (counts['released'], counts['queued']) == (3, 0) and added_up(counts)


def test_the_predicted_end_adds_the_held_motions(sequencer, clock):
    sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer, duration=0.4)
    release = sequencer.released(sequencer.take_for_release(), clock.now)
    sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer, duration=0.3)
    sequencer.submit(PICK, PLACE, 'pick_place')  # waiting: its duration is unknown
    assert sequencer.predicted_end(clock.now) == pytest.approx(release.latest_end + 0.3)
    assert len(sequencer) == 2


def test_a_plan_that_ends_after_the_previous_motion_made_the_robot_wait(sequencer, clock):
    sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer, duration=0.4)
    sequencer.released(sequencer.take_for_release(), clock.now)
    sequencer.submit(PICK, PLACE, 'pick_place')  # arrives while the first one runs
    request, start = sequencer.take_for_planning()
    clock.now += 1.0  # the plan takes longer than the running motion
    sequencer.plan_finished(motion_of(request, start))
    release = sequencer.released(sequencer.take_for_release(), clock.now)
    assert release.waited_for_planner
    assert release.release_delay() == pytest.approx(1.0 - 0.4 - 0.002)


def counted_notifications(sequencer):
    """Return a list that each wake-up of the sequencer's waiters from now on adds to."""
    notified = []
    condition = sequencer._condition
    notify_all = condition.notify_all

    def counting():
        notified.append(True)
        notify_all()
    condition.notify_all = counting
    return notified


def test_finish_and_take_hands_a_motion_due_at_once_to_its_caller_without_a_wake_up(clock):
    sequencer = Sequencer(3, clock=clock)
    sequencer.submit(PICK, PLACE, 'pick_place')
    request, start = sequencer.take_for_planning()
    notified = counted_notifications(sequencer)
    held, due = sequencer.finish_and_take(motion_of(request, HOME))
    assert due is held and held.ready == clock.now and held.request is request
    assert sequencer.take_for_release() is None, 'taken already'
    assert notified == [], 'nothing left for a release thread'
    sequencer.released(due, clock.now)
    # The robot busy: the motion stays held, for the release thread, which is woken.
    sequencer.submit(PICK, PLACE, 'pick_place')
    request, start = sequencer.take_for_planning()
    notified.clear()
    held, due = sequencer.finish_and_take(motion_of(request, start))
    assert due is None and held is not None and notified == [True]
    assert sequencer.take_for_release() is None, 'the first one still runs'
    assert sequencer.take_for_release(sequencer.last_release.latest_end) is held
    counts = sequencer.counts()
    assert (counts['planned'], counts['released']) == (2, 1) and added_up(counts)
    # Cleared while planned: neither held nor taken, counted as dropped, waiters woken.
    sequencer.submit(PICK, PLACE, 'pick_place')
    request, start = sequencer.take_for_planning()
    assert sequencer.clear() == [3]
    notified.clear()
    assert sequencer.finish_and_take(motion_of(request, start)) == (None, None)
    assert notified == [True]
    counts = sequencer.counts()
    assert counts['dropped_cleared'] == 1 and added_up(counts)


def test_clear_drops_waiting_planning_and_held_pairs_but_not_the_running_one(clock):
    sequencer = Sequencer(10, clock=clock)
    for _ in range(5):
        sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer)
    running = sequencer.released(sequencer.take_for_release(), clock.now)
    plan_next(sequencer)  # pair 2 held
    request, start = sequencer.take_for_planning()  # pair 3 being planned
    assert sequencer.clear() == [2, 3, 4, 5]
    assert sequencer.last_release is running and sequencer.running() is running
    assert not sequencer.plan_finished(motion_of(request, start)), 'cleared while planned'
    assert sequencer.take_for_release(running.latest_end) is None
    counts = sequencer.counts()
    assert (counts['dropped'], counts['released'], counts['queued']) == (4, 1, 0)
    assert added_up(counts)
    assert sequencer.clear() == []
    # A pair cleared while planned whose plan then fails is dropped too, not rejected.
    sequencer.submit(PICK, PLACE, 'pick_place')
    sequencer.take_for_planning()
    assert sequencer.clear() == [6]
    assert not sequencer.plan_failed('unreachable')
    counts = sequencer.counts()
    assert (counts['dropped'], counts['rejected']) == (5, 0) and added_up(counts)
    assert counts['dropped_cleared'] == 5


def test_at_the_stop_every_pair_still_in_the_queue_is_dropped_and_named(clock):
    sequencer = Sequencer(10, clock=clock)
    for _ in range(6):
        sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer)
    assert sequencer.take_for_release() is not None  # pair 1 taken for release
    plan_next(sequencer)  # pair 2 held
    request, start = sequencer.take_for_planning()  # pair 3 being planned
    sequencer.stop()
    # The workers end what they had: the plan is not held, the release not published.
    assert sequencer.plan_finished(motion_of(request, start)) is None
    sequencer.release_failed('stopped')
    assert sequencer.take_dropped_while_stopped() == [3, 1]
    assert sequencer.take_dropped_while_stopped() == []
    # What still waits or is held: dropped as stopped by the one who stops.
    assert sequencer.clear('stopped') == [2, 4, 5, 6]
    counts = sequencer.counts()
    assert (counts['dropped_stopped'], counts['queued'], counts['releasing']) == (6, 0, 0)
    assert added_up(counts) and 'dropped_cleared' not in counts


def test_a_plan_still_running_when_the_queue_is_dropped_counts_as_that_drop(clock):
    sequencer = Sequencer(10, clock=clock)
    sequencer.submit(PICK, PLACE, 'pick_place')
    sequencer.take_for_planning()
    sequencer.stop()
    assert sequencer.clear('stopped') == [1]  # named here: not again when its plan ends
    assert not sequencer.plan_failed('unreachable')
    assert sequencer.take_dropped_while_stopped() == []
    counts = sequencer.counts()
    assert (counts['dropped_stopped'], counts['rejected']) == (1, 0) and added_up(counts)


def test_every_waiting_place_expires_at_once_with_the_reason():
    pairing = PosePairing()
    for stamp in ((1, 0), (2, 0)):
        assert pairing.take_pick(stamp, 'stamp', wait=0.5, depth=10) is None
        pairing.hold_place(stamp, f'place {stamp}', now=0.0, wait=0.5)
    pairing.expire_all_places('before the node stopped')
    errors = pairing.expired_places(0.0)  # long before their deadline
    assert [error.kind for error in errors] == ['unpaired', 'unpaired']
    assert all('before the node stopped' in str(error) for error in errors)
    assert '(1, 0)' in str(errors[0]) and '(2, 0)' in str(errors[1])
    assert pairing.waiting_places == 0


def test_a_motion_that_fails_at_release_is_dropped_and_counted(sequencer, clock):
    sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer)
    assert sequencer.take_for_release() is not None
    assert sequencer.counts()['releasing'] == 1
    sequencer.release_failed('off_trajectory')
    counts = sequencer.counts()
    assert (counts['dropped'], counts['releasing']) == (1, 0) and added_up(counts)
    assert counts['dropped_off_trajectory'] == 1


def test_release_timing_rejects_an_unknown_stamp_mode():
    assert release_timing(1.0, 'zero', PERIOD, 0.004) == (1.0, 1.0 + PERIOD, None)
    assert release_timing(1.0, 'ahead', PERIOD, 0.004) == (1.004, 1.004, 1.004)
    with pytest.raises(InvalidInputError, match='header_stamp'):
        release_timing(1.0, 'now', PERIOD, 0.004)


def test_the_blocking_waits_return_when_due_and_on_stop():
    sequencer = Sequencer(4)  # real monotonic clock
    assert sequencer.next_to_plan(0.01) is None and sequencer.wait_for_release(0.01) is None
    sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer, duration=0.05)
    first = sequencer.wait_for_release(1.0)
    release = sequencer.released(first, time.monotonic())
    sequencer.submit(PICK, PLACE, 'pick_place')
    plan_next(sequencer, duration=0.05)
    second = sequencer.wait_for_release(1.0, spin=0.02)  # sleeps, then polls the clock
    assert second is not None and time.monotonic() >= release.latest_end
    results = []
    waiter = threading.Thread(target=lambda: results.append(sequencer.next_to_plan(5.0)))
    waiter.start()
    sequencer.stop()
    waiter.join(5.0)
    assert results == [None] and sequencer.stopped


# --- where the robot is at release ------------------------------------------------------

@pytest.fixture(scope='module')
def planned():
    """Return a PlannedMotion of a real plan from HOME through PICK to PLACE, and the next."""
    sequencer = Sequencer(2, clock=FakeClock())
    first = sequencer.submit(PICK, PLACE, 'pick_place')
    second = sequencer.submit(HOME, PICK, 'pick_place')
    motions = []
    for request, start in ((first, HOME), (second, PLACE)):
        plan = plan_cycle(start, request.pick, request.place, CONFIG)
        motions.append(PlannedMotion(request, plan.joint_trajectory, start, plan.end_position,
                                     0.0))
    return motions


def test_the_start_check_against_a_fresh_joint_state(planned, clock):
    first, second = planned
    sequencer = Sequencer(2, clock=clock)
    assert check_start(first, None, None, 0.0, CONFIG.geometry, 1e-3).action == 'publish'
    check = check_start(first, None, HOME + [0.0, 0.0005, 0.0], 0.0, CONFIG.geometry, 1e-3)
    assert (check.action, check.basis) == ('publish', 'joint_states')
    assert check.distance == pytest.approx(5e-4)
    jogged = HOME + [0.01, 0.0, 0.0]
    check = check_start(first, None, jogged, 0.0, CONFIG.geometry, 1e-3)
    assert check.action == 'replan' and np.array_equal(check.position, jogged)
    release = sequencer.released(first, 10.0)
    # Measured after the first motion's end: compared with the second motion's start.
    after = release.latest_end + 0.001
    assert check_start(second, release, PLACE, after, CONFIG.geometry, 1e-3).action == 'publish'
    check = check_start(second, release, jogged, after, CONFIG.geometry, 1e-3)
    assert check.action == 'replan' and check.basis == 'joint_states'


def test_a_joint_state_measured_during_the_motion_is_compared_with_the_motion(planned, clock):
    first, second = planned
    release = Sequencer(2, clock=clock).released(first, 10.0)
    duration = first.duration
    # Where the robot is on track 3 ms before the end (still short of it, moving slowly): no
    # re-plan, whichever cycle the zero-stamped trajectory started at.
    for started in (release.earliest_start, release.latest_start):
        measured_at = started + duration - 0.003
        on_track = forward_kinematics(
            quintic_interpolate(first.trajectory, duration - 0.003)[0], CONFIG.geometry)
        assert track_deviation(release, on_track, measured_at, CONFIG.geometry) < 1e-6
        check = check_start(second, release, on_track, measured_at, CONFIG.geometry, 1e-3)
        assert (check.action, check.basis) == ('publish', 'joint_states_on_track')
    # Off the trajectory (the controller aborted): wait for a joint state after its end.
    off = PLACE + [0.0, 0.0, 0.02]
    check = check_start(second, release, off, release.latest_start + duration - 0.003,
                        CONFIG.geometry, 1e-3)
    assert check.action == 'wait' and check.distance > 0.01
    # No joint state: the robot is at the end of the last motion.
    check = check_start(second, release, None, 0.0, CONFIG.geometry, 1e-3)
    assert (check.action, check.basis) == ('publish', 'last_trajectory')


def dwelling(request, start, duration=0.4, rest=0.035):
    """Return a PlannedMotion to the place of ``request`` that rests ``rest`` s at its end."""
    move = motion_of(request, start, duration - rest).trajectory
    trajectory = JointTrajectoryData(
        move.joint_names, [0.0, duration - rest, duration],
        np.vstack((move.positions, move.positions[-1:])), np.zeros((3, 3)), np.zeros((3, 3)))
    return PlannedMotion(request, trajectory, np.asarray(start, dtype=float), request.place,
                         plan_time=0.01)


def test_with_ahead_stamps_a_held_motion_is_handed_over_during_the_final_dwell(clock):
    sequencer = Sequencer(4, clock=clock)
    requests = [sequencer.submit(PICK, PLACE, 'pick_place') for _ in range(3)]
    for request in requests:
        taken, start = sequencer.take_for_planning()
        sequencer.plan_finished(dwelling(taken, HOME if start is None else start))
    first = sequencer.released(sequencer.take_for_release(), clock.now, 'ahead', PERIOD, 0.004)
    assert first.motion.final_rest == pytest.approx(0.035)
    dwell_start = first.latest_end - 0.035
    # A zero stamp would start at once: only after the end; ahead: from the dwell's start.
    assert sequencer.due(clock.now) == pytest.approx(first.latest_end)
    assert sequencer.due(clock.now, handover_rest=0.004) == pytest.approx(dwell_start)
    assert sequencer.due(clock.now, handover_rest=0.05) == pytest.approx(first.latest_end)
    clock.now = dwell_start - 1e-6
    assert sequencer.take_for_release(handover_rest=0.004) is None, 'still moving'
    clock.now = dwell_start
    motion = sequencer.take_for_release(handover_rest=0.004)
    assert sequencer.stamp_for(clock.now, 0.004) == pytest.approx(first.latest_end)
    second = sequencer.released(motion, clock.now, 'ahead', PERIOD, 0.004)
    assert second.stamp == pytest.approx(first.latest_end), 'starts exactly as the first ends'
    assert second.predicted_gap() == pytest.approx((0.0, 0.0))
    assert second.release_delay() == pytest.approx(-0.035)
    # Released late in the dwell (less than release_lead before its end): stamp ahead as usual.
    clock.now = second.latest_end - 0.001
    third = sequencer.released(sequencer.take_for_release(handover_rest=0.004), clock.now,
                               'ahead', PERIOD, 0.004)
    assert third.stamp == pytest.approx(clock.now + 0.004)


def test_a_move_without_a_final_dwell_has_no_rest(planned):
    first, _ = planned
    assert first.final_rest == 0.0
