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

"""
Sequencing of pick-and-place cycles for a controller that replaces its running trajectory.

ros2_controllers' joint_trajectory_controller on Jazzy (branch ``jazzy``) replaces the
running trajectory at the next control cycle after a new message arrives, whatever its
``header.stamp`` (``JointTrajectoryController::update()``, src/joint_trajectory_controller.cpp
lines 273-315). At the first sample of the new trajectory it takes the measured state
(position, velocity if there is a velocity state interface, acceleration 0) and splines each
joint from it straight to the first point, reached at ``stamp + time_from_start[0]``
(``Trajectory::sample()``, src/trajectory.cpp lines 148-168); a zero stamp starts at that
cycle. So a trajectory sent while another runs cuts the running one short. This module
therefore keeps planned trajectories back and releases each only once the one before it has
ended:

* intake (:meth:`Sequencer.submit`, fast, called from subscription callbacks) puts a pair in a
  bounded queue, or rejects the newest pair when the queue is full;
* planning (:meth:`Sequencer.next_to_plan`, one worker) plans the pairs one by one in arrival
  order (belt picks: in latch order), each from the end of the motion planned before it, and
  holds the result;
* release (:meth:`Sequencer.wait_for_release`, one worker) hands the oldest held motion over
  when the motion released before it has ended at the latest (see :class:`Release`), or, with
  ``ahead`` stamps, as soon as that motion rests in its final dwell, stamped to start exactly
  when the dwell ends (see :meth:`Sequencer.due`).

The class is thread-safe (one :class:`threading.Condition`) and ROS-free; its clock is
injected so the logic is tested with a fake one. :class:`PosePairing` pairs picks and places
arriving on separate topics.
"""

from collections import Counter, deque, OrderedDict
from dataclasses import dataclass, field, replace
import threading
import time

import numpy as np

from .errors import EllipathError, InvalidInputError
from .joint_trajectory import JointTrajectoryData, quintic_interpolate, REST_TOLERANCE
from .kinematics import forward_kinematics
from .settings import SETTING_BY_NAME, validate

PAIRING_MODES = SETTING_BY_NAME['pairing'].choices
# zero: the controller starts the trajectory at the cycle that picks it up;
# ahead: stamp = publication + release_lead, so the start is known exactly.
HEADER_STAMPS = SETTING_BY_NAME['header_stamp'].choices
# What the node did with pairs; see Sequencer.counts.
COUNTERS = ('received', 'planned', 'released', 'rejected', 'dropped')
# What became of pick_pose messages; see PosePairing.counts.
PICK_COUNTERS = ('received', 'paired', 'invalid', 'replaced', 'evicted', 'cleared')
# Samples of the running trajectory over the window of its uncertain start when a joint state
# measured during it is compared with where it should be (0.06 ms apart for a 2 ms window).
_TRACK_SAMPLES = 33


class UnpairedPlaceError(EllipathError):
    """A place pose arrived with no pick pose to pair it with."""

    kind = 'unpaired'


class QueueFullError(EllipathError):
    """The cycle queue holds ``queue_depth`` pairs: the newest pair (``pair``) is rejected."""

    kind = 'queue_full'

    def __init__(self, message, pair):
        super().__init__(message)
        self.pair = pair


class PosePairing:
    """
    Pick positions waiting for their place, at most ``depth`` of them, and a ledger of picks.

    In ``stamp`` mode a place pairs with the pick of identical stamp (any hashable key, the
    node passes ``(sec, nanosec)``); a lost message then leaves an unpaired pick or place and
    never joins a place with another pick. In ``sequence`` mode a place pairs with the
    pending pick and a second pick replaces the first, which mis-pairs when a place is lost.
    Not thread-safe: the node uses it from one mutually exclusive callback group only (other
    threads only read :meth:`counts`, a copy).

    Every pick counted as received ends in exactly one of: paired, pending, invalid (see
    :meth:`reject_pick`), replaced (a pick of the same key came), evicted (``depth`` picks
    were waiting: the oldest goes) or cleared (the pairing mode changed). Each pick that is
    dropped leaves a notice (kind, text) for the caller to report, see :meth:`take_notices`.

    Two topics keep no order between them: a place can be read before the pick sent ahead
    of it (seen under load: 2 of 900 two-topic pairs in a 30-minute soak). In ``stamp`` mode
    a place whose pick has not arrived therefore waits for it (:meth:`take_pick` with
    ``wait``, then :meth:`hold_place`), up to ``wait`` seconds; its pick then returns it from
    :meth:`add_pick`, and :meth:`expired_places` hands back those whose pick did not come in
    time (or that a change of mode cleared) as :class:`UnpairedPlaceError`, for the caller to
    reject with a status. A pick is only ever joined with the place of its own stamp.
    """

    def __init__(self):
        self._pending = OrderedDict()
        # Places waiting for their pick: key -> (place, deadline [s], wait [s]), oldest first.
        self._places = OrderedDict()
        self._expired = []
        self._mode = PAIRING_MODES[0]
        self._counts = dict.fromkeys(PICK_COUNTERS, 0)
        self._notices = []
        self._dropped_keys = []

    def __len__(self):
        """Return the number of pending picks."""
        return len(self._pending)

    def counts(self):
        """
        Return the pick ledger as a dict (``pending`` included).

        ``received`` = ``paired`` + ``pending`` + ``invalid`` + ``replaced`` + ``evicted`` +
        ``cleared``.
        """
        counts = dict(self._counts)
        counts['pending'] = len(self._pending)
        return counts

    @property
    def waiting_places(self):
        """
        Return the number of places held and not yet answered (see :meth:`hold_place`).

        Those waiting for their pick and those whose wait is over (expired, cleared or
        replaced) but not yet handed back by :meth:`expired_places`.
        """
        return len(self._places) + len(self._expired)

    def take_notices(self):
        """Return the (kind, text) of each pick dropped since the last call, oldest first."""
        notices, self._notices = self._notices, []
        return notices

    def take_dropped_keys(self):
        """Return the keys (see :meth:`key`) of the picks dropped since the last call."""
        keys, self._dropped_keys = self._dropped_keys, []
        return keys

    def _drop(self, kind, key, text):
        self._counts[kind] += 1
        self._notices.append((f'pick_{kind}', text))
        self._dropped_keys.append(key)

    @staticmethod
    def key(stamp, mode):
        """Return the key under which a pick of ``stamp`` waits in ``mode``."""
        return None if mode == 'sequence' else stamp

    def _key(self, stamp, mode):
        """Return the key pairing a pick and a place in ``mode``; a new mode drops every pick."""
        if mode != self._mode:
            for key in self._pending:
                self._drop('cleared', key, f'pick_pose (stamp {key}) dropped: pairing changed '
                           f'from {self._mode} to {mode}')
            self._pending.clear()
            self.expire_all_places(f'before the pairing changed from {self._mode} to {mode}')
            self._mode = mode
        return self.key(stamp, mode)

    def reject_pick(self):
        """Count a pick_pose that failed validation (the caller reports why)."""
        self._counts['received'] += 1
        self._counts['invalid'] += 1

    def add_pick(self, stamp, position, mode, depth):
        """
        Store a pick, or return the place waiting for it (the pick is then paired).

        A pick it displaces leaves a notice (see :meth:`take_notices`). Returns the held
        place (see :meth:`hold_place`) whose stamp is this pick's, else None.
        """
        key = self._key(stamp, mode)
        self._counts['received'] += 1
        if key is not None and key in self._places:
            place, _, _ = self._places.pop(key)
            self._counts['paired'] += 1
            return place
        if key in self._pending:
            del self._pending[key]
            self._drop('replaced', key,
                       'pick_pose replaced the pending pick, which had no place_pose yet'
                       if key is None else
                       f'pick_pose replaced the pending pick of the same stamp {key}')
        elif len(self._pending) >= depth:
            dropped, _ = self._pending.popitem(last=False)
            self._drop('evicted', dropped, f'pick queue full ({depth} waiting): dropped the '
                       f'oldest pick (stamp {dropped})')
        self._pending[key] = position
        return None

    def take_pick(self, stamp, mode, wait=0.0, depth=0):
        """
        Remove and return the pick position paired with a place, or raise.

        With ``wait`` > 0 in ``stamp`` mode and fewer than ``depth`` places waiting, a place
        whose pick has not arrived yet gets None instead: hold it with :meth:`hold_place`.
        """
        key = self._key(stamp, mode)
        try:
            position = self._pending.pop(key)
        except KeyError:
            if key is not None and wait > 0.0 and len(self._places) < depth:
                return None
            wanted = 'a pending pick_pose' if key is None else f'a pick_pose with stamp {key}'
            raise UnpairedPlaceError(
                f'place_pose: expected {wanted} to pair with (pairing {mode}), got none'
            ) from None
        self._counts['paired'] += 1
        return position

    def hold_place(self, stamp, place, now, wait):
        """
        Keep ``place`` (anything) for the pick of ``stamp`` until ``now`` + ``wait`` [s].

        Only after :meth:`take_pick` returned None for that stamp. A second place of the
        same stamp replaces the first, which expires at once (see :meth:`expired_places`).
        """
        if stamp in self._places:
            del self._places[stamp]
            self._expired.append(UnpairedPlaceError(
                f'place_pose: expected one place_pose per stamp, got a second with stamp '
                f'{stamp} before its pick_pose: the first is dropped'))
        self._places[stamp] = (place, now + wait, wait)

    def expire_all_places(self, why):
        """Make every place waiting for its pick expire now (see :meth:`expired_places`)."""
        self._expired.extend(UnpairedPlaceError(
            f'place_pose: expected a pick_pose with stamp {key} to pair with, got none {why}')
            for key in self._places)
        self._places.clear()

    def expired_places(self, now):
        """
        Remove the places whose pick did not come by their deadline; return their errors.

        Oldest first, with those cleared by a change of mode or replaced (see
        :meth:`hold_place`); each is a place to reject as unpaired.
        """
        expired, self._expired = self._expired, []
        for key in [key for key, (_, deadline, _) in self._places.items() if deadline <= now]:
            _, _, wait = self._places.pop(key)
            expired.append(UnpairedPlaceError(
                f'place_pose: expected a pick_pose with stamp {key} to pair with, got none '
                f'within {wait:g} s'))
        return expired


@dataclass(frozen=True)
class PairRequest:
    """
    One pick/place pair taken in by the queue.

    Attributes
    ----------
    number : int
        Position in arrival order, from 1.
    pick, place : numpy.ndarray
        TCP positions [m], shape (3,).
    received : float
        Clock time of the intake [s].
    topic : str
        Where the pair came from (``place_pose`` or ``pick_place``), for statuses.
    latch_time : float or None
        When the object was at ``pick`` (its header.stamp, node clock) [s]; belt picks.

    """

    number: int
    pick: np.ndarray
    place: np.ndarray
    received: float
    topic: str
    latch_time: float | None = None


@dataclass(frozen=True)
class PlannedMotion:
    """
    A planned pair, held until its release.

    Attributes
    ----------
    request : PairRequest
        The pair.
    trajectory : JointTrajectoryData
        What will be published, first point at ``time_from_start`` 0.
    start_position, end_position : numpy.ndarray
        TCP at the first and the last point [m].
    plan_time : float
        Time spent planning [s].
    ready : float or None
        Clock time at which the plan was held (set by :meth:`Sequencer.plan_finished`).
    details : dict
        Anything the caller wants to keep with the motion (plan metrics).

    """

    request: PairRequest
    trajectory: JointTrajectoryData
    start_position: np.ndarray
    end_position: np.ndarray
    plan_time: float
    ready: float | None = None
    details: dict = field(default_factory=dict)

    @property
    def duration(self):
        """Duration of the trajectory [s]."""
        return self.trajectory.duration

    @property
    def final_rest(self):
        """Return how long the trajectory rests at its last point before its end [s]."""
        return final_rest(self.trajectory)


def final_rest(trajectory):
    """
    Return how long a JointTrajectoryData rests at its last point before its end [s].

    A dwell (``place_dwell``) is a last segment between two points of equal positions with
    zero velocities and accelerations (to ``REST_TOLERANCE``, the rounding left by the
    timing): JTC's quintic there is constant. A belt pick onto a moving place ends with its
    exit, not at rest before its end: 0.
    """
    times = trajectory.time_from_start
    if times.size < 2:
        return 0.0
    at_rest = all(np.all(np.abs(values) <= REST_TOLERANCE) for values in (
        trajectory.positions[-1] - trajectory.positions[-2], trajectory.velocities[-2:],
        trajectory.accelerations[-2:]))
    return float(times[-1] - times[-2]) if at_rest else 0.0


@dataclass(frozen=True)
class Release:
    """
    A motion handed to the controller, and when it runs (clock times, s).

    A zero-stamped trajectory published at ``published`` starts at the first control cycle
    after it arrives: not before ``published`` and at the latest ``controller_period`` later
    (transport on one host takes some tens of microseconds and is neglected). An ``ahead``
    stamp starts exactly at the stamp. The next motion is released at ``latest_end``, or during
    a final dwell long enough (``ahead`` only, see :meth:`Sequencer.due`), so the controller
    never replaces a trajectory while it moves the robot.

    Attributes
    ----------
    motion : PlannedMotion
        The motion.
    published : float
        Clock time of publication.
    earliest_start, latest_start : float
        Bounds of the start of the trajectory on the controller.
    stamp : float or None
        Clock time written as ``header.stamp`` (``ahead``), None for a zero stamp.
    previous_end : float or None
        Latest end of the motion released before it, None if there was none.
    previous_earliest_end : float or None
        Earliest end of the motion released before it, None if there was none.
    waited_for_planner : bool
        True when the plan was not ready by ``previous_end``: the robot waited for it.

    """

    motion: PlannedMotion
    published: float
    earliest_start: float
    latest_start: float
    stamp: float | None = None
    previous_end: float | None = None
    previous_earliest_end: float | None = None
    waited_for_planner: bool = False

    @property
    def latest_end(self):
        """Latest clock time at which the trajectory has ended [s]."""
        return self.latest_start + self.motion.duration

    @property
    def earliest_end(self):
        """Earliest clock time at which the trajectory ends [s]."""
        return self.earliest_start + self.motion.duration

    def release_delay(self):
        """
        Return publication minus the latest end of the previous motion [s], or None.

        Negative for a release during the previous motion's final dwell.
        """
        return None if self.previous_end is None else self.published - self.previous_end

    def predicted_gap(self):
        """
        Return the bounds (low, high) of the idle time after the previous motion [s], or None.

        A prediction from the publication times, not a measurement on the controller:
        low = this earliest start - previous latest end, high = this latest start - previous
        earliest end. Each start falls on a control cycle inside its window, so with a zero
        stamp the idle time is within the bounds; with ``ahead`` stamps both are exact.
        """
        if self.previous_end is None:
            return None
        return (self.earliest_start - self.previous_end,
                self.latest_start - self.previous_earliest_end)


def release_timing(published, header_stamp, controller_period, release_lead, previous_end=None):
    """
    Return (earliest start, latest start, stamp) of a trajectory published at ``published``.

    Parameters
    ----------
    published : float
        Clock time of publication [s].
    header_stamp : str
        ``'zero'`` (start at the cycle that picks it up) or ``'ahead'``.
    controller_period : float
        The controller's update period [s].
    release_lead : float
        Stamp ahead of the publication in ``'ahead'`` mode [s]; it must exceed transport plus
        one controller period, or the controller starts the trajectory late, mid-motion.
    previous_end : float or None
        Latest end of the motion released before. With ``'ahead'`` the stamp is never before
        it: a trajectory released during the previous one's final dwell starts exactly when
        that one ends.

    """
    if header_stamp == 'ahead':
        stamp = published + release_lead
        if previous_end is not None:
            stamp = max(stamp, previous_end)
        return stamp, stamp, stamp
    if header_stamp != 'zero':
        raise InvalidInputError(
            f'header_stamp: expected one of {", ".join(HEADER_STAMPS)}, got {header_stamp!r}')
    return published, published + controller_period, None


class Sequencer:
    """
    The cycle queue: pairs waiting to be planned, planned motions held, and the release.

    Parameters
    ----------
    depth : int
        Most pairs in the queue (waiting, being planned and held together); the range of
        ``queue_depth`` in :mod:`.settings`.
    clock : callable, optional
        Returns the current time [s]; :func:`time.monotonic` by default. Blocking waits use
        real time whatever the clock, so tests with a fake clock use the non-blocking calls.

    """

    def __init__(self, depth, clock=time.monotonic):
        self.depth = validate('queue_depth', depth)
        self.clock = clock
        self._condition = threading.Condition()
        self._waiting = deque()
        self._planning = None  # the request being planned
        self._planning_cancelled = None  # the kind of the clear that dropped it, if any
        self._held = deque()
        self._releasing = None  # the motion taken by the release worker, not yet published
        self._last_release = None
        self._numbers = 0
        self._stopped = False
        # Pairs the workers dropped once stopped (plan or release in progress), see
        # take_dropped_while_stopped.
        self._dropped_while_stopped = []
        self._counts = dict.fromkeys(COUNTERS, 0)
        self._kinds = Counter()  # (outcome, kind): pairs rejected or dropped, by kind

    # --- state ------------------------------------------------------------------------------

    def __len__(self):
        """Return the queue length: pairs waiting, being planned or held."""
        with self._condition:
            return self._length()

    def _length(self):
        """Return the queue length; the lock is held."""
        return len(self._waiting) + (self._planning is not None) + len(self._held)

    @property
    def waiting(self):
        """Return the number of pairs waiting to be planned."""
        with self._condition:
            return len(self._waiting)

    @property
    def stopped(self):
        """Return True once :meth:`stop` was called."""
        with self._condition:
            return self._stopped

    @property
    def last_release(self):
        """Return the latest :class:`Release`, or None."""
        with self._condition:
            return self._last_release

    def counts(self):
        """
        Return what happened to every pair so far, as a dict.

        ``received`` = ``released`` + ``rejected`` + ``dropped`` + ``queued`` (waiting, being
        planned or held) + ``releasing`` (taken for release, being checked and published).
        ``planned`` counts successful plans (a pair re-planned at release or put back by
        :meth:`requeue_held` counts once).
        ``rejected_<kind>`` and ``dropped_<kind>`` split ``rejected`` and ``dropped`` by the
        kind of their status (``queue_full``, ``unpaired``, ``cleared``, ...).
        """
        with self._condition:
            counts = dict(self._counts)
            counts.update(queued=self._length(), held=len(self._held),
                          releasing=int(self._releasing is not None))
            counts.update((f'{outcome}_{kind}', count)
                          for (outcome, kind), count in sorted(self._kinds.items()))
        return counts

    def _count(self, outcome, kind, number=1):
        """Count ``number`` pairs rejected or dropped as ``kind``; the lock is held."""
        self._counts[outcome] += number
        self._kinds[outcome, kind] += number

    def running(self, now=None):
        """Return the last release if its trajectory may still run at ``now``, else None."""
        now = self.clock() if now is None else now
        with self._condition:
            last = self._last_release
        return last if last is not None and now < last.latest_end else None

    def tail_motion(self):
        """Return the motion the next plan follows (last held, else releasing), or None."""
        with self._condition:
            if self._held:
                return self._held[-1]
            return self._releasing

    def predicted_end(self, now=None):
        """
        Return the latest clock time at which every held motion has ended [s].

        Held motions run back to back after the running one; pairs not yet planned are not
        counted (their duration is unknown). ``now`` if nothing runs or is held.
        """
        now = self.clock() if now is None else now
        with self._condition:
            end = now
            if self._last_release is not None:
                end = max(end, self._last_release.latest_end)
            return end + sum(motion.duration for motion in self._held)

    # --- intake -----------------------------------------------------------------------------

    def submit(self, pick, place, topic, latch_time=None):
        """
        Take a pair into the queue and return its :class:`PairRequest`.

        ``latch_time``: when the object was at ``pick`` (belt picks), see PairRequest.

        Raises
        ------
        QueueFullError
            The queue holds ``depth`` pairs; the pair is counted as received and rejected.

        """
        with self._condition:
            self._numbers += 1
            self._counts['received'] += 1
            if self._length() >= self.depth:
                self._count('rejected', QueueFullError.kind)
                raise QueueFullError(
                    f'pair {self._numbers}: expected room in the cycle queue, got '
                    f'{self._length()} pairs queued (queue_depth {self.depth}): the newest '
                    'pair is rejected', self._numbers)
            request = PairRequest(self._numbers, np.array(pick, dtype=float),
                                  np.array(place, dtype=float), self.clock(), topic,
                                  latch_time)
            self._waiting.append(request)
            self._condition.notify_all()
            return request

    def reject(self, kind='internal'):
        """
        Count a pair rejected before the queue (invalid, unpaired); return its number.

        So that every pair sent is accounted for, the caller counts each place_pose and each
        pick_place message as one pair, whether or not it could be paired and validated.
        ``kind``: the kind of its status (the error's ``kind``).
        """
        with self._condition:
            self._numbers += 1
            self._counts['received'] += 1
            self._count('rejected', kind)
            return self._numbers

    # --- planning ---------------------------------------------------------------------------

    def take_for_planning(self, now=None, by_latch=False):
        """
        Take the oldest waiting pair for planning, without blocking.

        With ``by_latch`` (belt picks), the pair latched first instead (its ``latch_time``;
        pairs latched together, or without a latch time, in arrival order): the rule of
        :func:`~.conveyor.next_belt_pick`'s ``latch`` order, the first object in latch order
        that can still be caught, the others waiting their turn; one the robot can no longer
        catch is rejected by its plan, with its status.

        Returns
        -------
        tuple or None
            (request, start) where start is the TCP [m] at which the motion must begin (the
            end of the last held motion, else of the running one) or None when the robot is
            at rest and the caller must find out where; None when nothing waits.

        """
        now = self.clock() if now is None else now
        with self._condition:
            if not self._waiting or self._planning is not None:
                return None
            if by_latch:
                request = min(self._waiting, key=_latch_order)
                self._waiting.remove(request)
            else:
                request = self._waiting.popleft()
            self._planning, self._planning_cancelled = request, None
            return request, self._motions_end(now)

    def _motions_end(self, now):
        """
        Return where the motions planned so far leave the robot [m], or None; lock held.

        The end of the last held motion, else of the one being released, else of the
        released one while it may run; None when the robot is at rest.
        """
        if self._held:
            return self._held[-1].end_position
        if self._releasing is not None:
            return self._releasing.end_position
        if self._last_release is not None and now < self._last_release.latest_end:
            return self._last_release.motion.end_position
        return None

    def predicted_start(self, now=None):
        """
        Return the TCP [m] a pair submitted now would be planned from, or None.

        The place of the last pair ahead of it (waiting or being planned: a cycle ends
        exactly at its place), else what :meth:`take_for_planning` would give (None: the
        robot at rest, where the caller must find out). Static picks: in latch order (a
        moving belt) a pair may be planned before those waiting.
        """
        now = self.clock() if now is None else now
        with self._condition:
            if self._waiting:
                return self._waiting[-1].place
            if self._planning is not None:
                return self._planning.place
            return self._motions_end(now)

    def wake(self):
        """Wake the workers blocked in :meth:`next_to_plan` (to look at their ``until``)."""
        with self._condition:
            self._condition.notify_all()

    def next_to_plan(self, timeout, by_latch=False, until=None):
        """
        Block up to ``timeout`` s for :meth:`take_for_planning`; None on timeout or stop.

        ``until``: also None as soon as it returns true (called with the lock held, after
        each wake-up, when no pair waits: it must be quick and take no lock of the caller
        that is held while calling this object).
        """
        deadline = time.monotonic() + timeout
        with self._condition:
            while not self._stopped:
                taken = self.take_for_planning(by_latch=by_latch)
                if taken is not None:
                    return taken
                remaining = deadline - time.monotonic()
                if remaining <= 0.0 or (until is not None and until()):
                    return None
                self._condition.wait(remaining)
        return None

    def plan_finished(self, motion):
        """
        Hold a planned motion; return it as held (with ``ready`` set).

        Returns None, and counts the pair as dropped, when the queue was cleared (or the
        sequencer stopped) while it was planned.
        """
        with self._condition:
            held = self._hold_planned(motion, self.clock())
            self._condition.notify_all()
            return held

    def finish_and_take(self, motion, handover_rest=None):
        """
        Hold a planned motion (:meth:`plan_finished`) and take the oldest held one if due now.

        In one step: (held, due), ``held`` as :meth:`plan_finished` returns it and ``due`` as
        :meth:`take_for_release` (None when not due, or when ``held`` is None). Waiters
        (:meth:`wait_for_release`) are woken only when a motion stays held: one taken here
        is the caller's to release, and a release thread woken for it would only take the
        GIL from the caller to find nothing.
        """
        with self._condition:
            now = self.clock()
            held = self._hold_planned(motion, now)
            due = None if held is None else self.take_for_release(now, handover_rest)
            if due is None or self._held:
                self._condition.notify_all()
            return held, due

    def _hold_planned(self, motion, now):
        """Hold ``motion`` ready at ``now`` and return it, or None if dropped; lock held."""
        self._counts['planned'] += 1
        if self._drop_planning():
            return None
        self._planning = None
        held = replace(motion, ready=now)
        self._held.append(held)
        return held

    def plan_failed(self, kind='internal'):
        """
        Count the pair being planned as rejected as ``kind`` (its plan failed); return True.

        Returns False, and counts it as dropped, when the queue was cleared while it was
        planned: the clear already reported it.
        """
        with self._condition:
            cancelled = self._drop_planning()
            if not cancelled:
                self._planning = None
                self._count('rejected', kind)
            self._condition.notify_all()
            return not cancelled

    def _drop_planning(self):
        """
        Count the pair being planned as dropped if cleared or stopped; return whether it was.

        The lock is held. One cleared was named by its clear; one dropped by the stop is kept
        for :meth:`take_dropped_while_stopped`.
        """
        request, self._planning = self._planning, None
        if self._planning_cancelled is not None:
            self._count('dropped', self._planning_cancelled)
        elif self._stopped:
            self._count('dropped', 'stopped')
            if request is not None:
                self._dropped_while_stopped.append(request.number)
        else:
            self._planning = request
            return False
        return True

    # --- release ----------------------------------------------------------------------------

    def due(self, now, handover_rest=None):
        """
        Return the clock time at which the oldest held motion may be released, or None.

        That is the latest end of the last released motion; with ``handover_rest`` (the node
        passes ``release_lead`` when ``header_stamp`` is ``ahead``), the start of that motion's
        final dwell if the dwell lasts at least ``handover_rest``: from then on the robot
        rests at the point where the held motion starts, so the controller's spline from the
        measured state (p, v = 0, a = 0) to that first point is constant, and the held motion,
        stamped at the end of the dwell, starts exactly then.
        """
        with self._condition:
            if not self._held or self._releasing is not None:
                return None
            last = self._last_release
            if last is None:
                return now
            handover = last.latest_end
            rest = last.motion.final_rest
            if handover_rest is not None and rest >= handover_rest:
                handover -= rest
            return max(now, handover)

    def take_for_release(self, now=None, handover_rest=None):
        """Take the oldest held motion if it is due at ``now``, without blocking; else None."""
        now = self.clock() if now is None else now
        with self._condition:
            due = self.due(now, handover_rest)
            if due is None or due > now:
                return None
            self._releasing = self._held.popleft()
            return self._releasing

    def wait_for_release(self, timeout, spin=0.0, handover_rest=None):
        """
        Block until the oldest held motion is due and take it; None on timeout or stop.

        The wait ends at the motion's due time on ``clock`` (``time.monotonic`` in the node);
        the caller then checks where the robot is, publishes, and reports
        :meth:`released` or :meth:`release_failed`. The last ``spin`` seconds before the due
        time are spent polling the clock (yielding the GIL between polls) instead of sleeping:
        a thread that sleeps until the due time may get a core only milliseconds later on a
        busy machine. ``handover_rest``: see :meth:`due`.
        """
        deadline = time.monotonic() + timeout
        with self._condition:
            while not self._stopped:
                now = self.clock()
                motion = self.take_for_release(now, handover_rest)
                if motion is not None:
                    return motion
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return None
                due = self.due(now, handover_rest)
                if due is not None and due - now <= spin:
                    self._condition.release()
                    try:
                        time.sleep(0.0)
                    finally:
                        self._condition.acquire()
                    continue
                self._condition.wait(
                    remaining if due is None else min(remaining, due - now - spin))
        return None

    def stamp_for(self, published, release_lead):
        """Return the ``ahead`` stamp of a motion published at ``published`` (clock time, s)."""
        with self._condition:
            last = self._last_release
            return release_timing(published, 'ahead', 0.0, release_lead,
                                  None if last is None else last.latest_end)[2]

    def released(self, motion, published, header_stamp='zero', controller_period=0.002,
                 release_lead=0.004, start=None):
        """
        Record that ``motion`` (taken for release) was published at ``published``.

        ``start``: the clock time of a stamp the caller chose (a belt pick starts exactly at
        the time its intercept was planned for); by default the stamp follows ``header_stamp``.

        Returns
        -------
        Release
            Its timing (see :func:`release_timing`) and its relation to the previous motion.

        """
        with self._condition:
            previous = self._last_release
            previous_end = None if previous is None else previous.latest_end
            earliest, latest, stamp = (
                (start, start, start) if start is not None else release_timing(
                    published, header_stamp, controller_period, release_lead, previous_end))
            release = Release(
                motion, published, earliest, latest, stamp, previous_end,
                None if previous is None else previous.earliest_end,
                waited_for_planner=(previous_end is not None and motion.ready is not None
                                    and motion.request.received < previous_end < motion.ready))
            self._last_release = release
            self._releasing = None
            self._counts['released'] += 1
            self._condition.notify_all()
            return release

    def release_failed(self, kind='internal'):
        """Count the motion taken for release as dropped as ``kind`` (not published)."""
        with self._condition:
            if self._stopped and self._releasing is not None:
                self._dropped_while_stopped.append(self._releasing.request.number)
            self._releasing = None
            self._count('dropped', kind)
            self._condition.notify_all()

    # --- clearing and stopping --------------------------------------------------------------

    def requeue_held(self, stale):
        """
        Put held motions back to be planned again, from the first for which ``stale`` is true.

        The held motions run back to back, each planned from the end of the one before, so
        those after a stale one go back too. Their pairs wait again at the front, in their
        order; ``planned`` counts each pair's plans once (see :meth:`counts`). Called by the
        planning worker between two plans (none is in progress then): a belt pick planned for
        a belt velocity that has since changed.

        Returns
        -------
        list of int
            The numbers of the pairs put back, in their order.

        """
        with self._condition:
            first = next((index for index, motion in enumerate(self._held) if stale(motion)),
                         None)
            if first is None:
                return []
            requests = [self._held.pop().request for _ in range(len(self._held) - first)]
            self._waiting.extendleft(requests)  # reversed twice: in their order
            self._counts['planned'] -= len(requests)
            self._condition.notify_all()
            return [request.number for request in reversed(requests)]

    def clear(self, kind='cleared'):
        """
        Drop every pair waiting, being planned or held as ``kind``; never the running trajectory.

        Returns
        -------
        list of int
            The numbers of the dropped pairs, in arrival order.

        """
        with self._condition:
            dropped = [request.number for request in self._waiting]
            dropped += [motion.request.number for motion in self._held]
            self._count('dropped', kind, len(self._waiting) + len(self._held))
            self._waiting.clear()
            self._held.clear()
            if self._planning is not None and self._planning_cancelled is None:
                # Counted as dropped once its plan ends (plan_finished or plan_failed).
                self._planning_cancelled = kind
                dropped.append(self._planning.number)
            self._condition.notify_all()
            return sorted(dropped)

    def stop(self):
        """
        Wake every blocked worker and make them return None from now on.

        The pairs still queued stay so until :meth:`clear` (with kind ``stopped``); a plan or
        a release in progress ends as dropped (``stopped``, see
        :meth:`take_dropped_while_stopped`).
        """
        with self._condition:
            self._stopped = True
            self._condition.notify_all()

    def take_dropped_while_stopped(self):
        """
        Return the numbers of the pairs dropped by a worker once stopped; forget them.

        A plan that ends after :meth:`stop` is not held (``dropped_stopped``), a motion taken
        for release is not published (:meth:`release_failed`): their statuses are the
        caller's, who stops.
        """
        with self._condition:
            numbers, self._dropped_while_stopped = self._dropped_while_stopped, []
            return numbers


def _latch_order(request):
    """Return the sort key of a waiting pair in latch order (see take_for_planning)."""
    if request.latch_time is None:
        return (0, 0.0, request.number)
    return (1, request.latch_time, request.number)


def track_deviation(release, measured, measured_at, geometry):
    """
    Return how far a measured TCP is from where the released motion puts the robot [m].

    Parameters
    ----------
    release : Release
        The last released motion.
    measured : numpy.ndarray
        TCP from the forward kinematics of a joint state [m], shape (3,).
    measured_at : float
        Clock time at which the joint state was measured (its stamp) [s].
    geometry : ellipath_ros.core.kinematics.DeltaGeometry
        Robot dimensions.

    Returns
    -------
    float
        Distance to the TCP of the motion at ``measured_at``; with a zero stamp the start is
        only known within [earliest_start, latest_start], and the smallest distance over that
        window is returned, so a joint state a few milliseconds old or a robot still a little
        short of the end near the stop does not count as a deviation. Before the earliest
        start the robot stands at the first point; after the latest end, at the last.

    """
    trajectory = release.motion.trajectory
    offsets = measured_at - np.linspace(release.earliest_start, release.latest_start,
                                        _TRACK_SAMPLES)
    offsets = np.clip(offsets, 0.0, trajectory.duration)
    expected = forward_kinematics(quintic_interpolate(trajectory, offsets)[0], geometry)
    return float(np.min(np.linalg.norm(expected - measured, axis=1)))


@dataclass(frozen=True)
class StartCheck:
    """
    Where the robot is when a held motion is released, and what to do about it.

    Attributes
    ----------
    action : str
        ``'publish'`` (the motion starts where the robot is), ``'replan'`` (re-plan it from
        ``position``) or ``'wait'`` (a joint state shows the robot off the running
        trajectory: wait for one measured after its end).
    position : numpy.ndarray or None
        Where the robot is [m] (``'replan'``), else None.
    distance : float
        Distance between the motion's start and the robot [m] (``'publish'``,
        ``'replan'``), or between the robot and the running trajectory (``'wait'``).
    basis : str
        What the robot position comes from: ``joint_states``, ``joint_states_on_track``
        (measured during the last motion and on it: the robot will be at its end),
        ``last_trajectory`` (no fresh joint state: the end of the last motion) or ``plan``
        (nothing known but what the plan started from).

    """

    action: str
    position: np.ndarray | None
    distance: float
    basis: str


def check_start(motion, last_release, measured, measured_at, geometry, tolerance):
    """
    Decide whether a held motion starts where the robot is, at its release.

    Parameters
    ----------
    motion : PlannedMotion
        The motion about to be released.
    last_release : Release or None
        The motion released before it.
    measured : numpy.ndarray or None
        TCP of the latest fresh joint state [m], or None if there is none.
    measured_at : float
        Clock time at which it was measured [s] (ignored when ``measured`` is None).
    geometry : ellipath_ros.core.kinematics.DeltaGeometry
        Robot dimensions.
    tolerance : float
        Largest distance accepted between the robot and the motion's start [m].

    Returns
    -------
    StartCheck

    """
    if measured is not None and (last_release is None or measured_at >= last_release.latest_end):
        robot, basis = np.asarray(measured, dtype=float), 'joint_states'
    elif last_release is None:
        return StartCheck('publish', None, 0.0, 'plan')
    else:
        if measured is not None:
            # Measured while the last motion may still run: it can only say whether the robot
            # follows that motion (then it will stop at its end), not where it will stop.
            deviation = track_deviation(last_release, measured, measured_at, geometry)
            if deviation > tolerance:
                return StartCheck('wait', None, deviation, 'joint_states')
        robot = last_release.motion.end_position
        basis = 'last_trajectory' if measured is None else 'joint_states_on_track'
    distance = float(np.linalg.norm(motion.start_position - robot))
    if distance > tolerance:
        return StartCheck('replan', robot, distance, basis)
    return StartCheck('publish', None, distance, basis)
