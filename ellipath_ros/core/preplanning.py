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
Approach legs planned while a pick waits for its place.

A request's approach leg (from where the robot will be to the pick) depends on the start and
the pick only. When picks and places come on separate topics, the pick comes first: the node
plans the approach then, while it waits for the place (:func:`~.planner.plan_approach`), so
that only the transfer leg lies between the place and the trajectory. :class:`ApproachCache`
keeps those legs, keyed by the pick's pairing key until the place pairs it, then by the pair's
number until the pair is planned, and decides whether one can be reused. It plans nothing
itself and knows nothing of ROS; it is thread-safe (one lock: intake adds, pairs and drops
picks, the planning thread plans and takes the legs).
"""

from collections import OrderedDict
import threading

import numpy as np

from .errors import InvalidInputError

# What became of the pre-planned approaches; see ApproachCache.counts.
APPROACH_COUNTERS = ('legs', 'hits', 'misses')


class _Slot:
    """A pick waiting for its place (or its pair for its plan), and its approach if planned."""

    __slots__ = ('pick', 'start', 'token', 'approach', 'attempted')

    def __init__(self, pick):
        self.pick = pick
        self.start = None  # where the approach was planned from, once attempted
        self.token = None  # the settings it was planned with (compared by identity)
        self.approach = None  # ApproachPlan, or None when not planned or its plan failed
        self.attempted = False

    def fits(self, start, tolerance, token):
        """Return whether it was planned from ``start`` (within ``tolerance``) with ``token``."""
        return (self.attempted and self.token is token
                and float(np.linalg.norm(self.start - start)) <= tolerance)


class ApproachCache:
    """
    Approach legs planned ahead, for at most ``depth`` picks waiting and ``depth`` pairs.

    A pick waiting for its place (:meth:`add`) gets a slot, keyed by its pairing key; the
    planning thread asks for a pick to plan (:meth:`next_to_plan`) and stores the leg, or its
    failure (:meth:`store`). When the place pairs the pick, the slot moves to the pair
    (:meth:`claim`); when the pair is planned, :meth:`take` hands the leg over if it is for the
    same pick, the same settings and a start within the tolerance of the pair's. Beyond
    ``depth`` the oldest slot goes (its pair is then planned in one go). A pick replaced,
    evicted or cleared by the pairing loses its slot (:meth:`add`, :meth:`discard`); a
    parameter change, ``clear_queue`` or a moving belt drops every slot (:meth:`clear`).

    The settings are an opaque token compared by identity: the node passes its settings
    snapshot, built anew on every parameter change.
    """

    def __init__(self, depth):
        if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
            raise InvalidInputError(f'depth: expected an integer >= 1, got {depth!r}')
        self.depth = depth
        self._lock = threading.Lock()
        self._pending = OrderedDict()  # pairing key -> _Slot, oldest first
        self._claimed = OrderedDict()  # pair number -> _Slot, oldest first
        self._counts = dict.fromkeys(APPROACH_COUNTERS, 0)

    def __len__(self):
        """Return the number of slots: picks waiting and pairs not yet planned."""
        with self._lock:
            return len(self._pending) + len(self._claimed)

    @property
    def waiting_picks(self):
        """Return the number of picks waiting for their place that have a slot."""
        with self._lock:
            return len(self._pending)

    def counts(self):
        """
        Return the counters as a dict.

        ``legs``: approach legs planned ahead (failed plans included); ``hits``: pairs
        given one by :meth:`take`; ``misses``: pairs given none (no leg ready: the place came
        first, the slot was dropped, the plan failed; or one for another start or other
        settings).
        """
        with self._lock:
            return dict(self._counts)

    def add(self, key, pick):
        """Give a pick waiting for its place a slot; one of the same key is replaced."""
        with self._lock:
            self._pending.pop(key, None)
            self._pending[key] = _Slot(np.array(pick, dtype=float))
            _bound(self._pending, self.depth)

    def discard(self, key):
        """Drop the slot of the pick of ``key`` (dropped by the pairing), if any."""
        with self._lock:
            self._pending.pop(key, None)

    def claim(self, key, number):
        """Move the slot of the pick of ``key`` to pair ``number`` (None: no pair, dropped)."""
        with self._lock:
            slot = self._pending.pop(key, None)
            if slot is not None and number is not None:
                self._claimed[number] = slot
                _bound(self._claimed, self.depth)

    def clear(self):
        """Drop every slot (parameters changed, the queue cleared, the belt moving)."""
        with self._lock:
            self._pending.clear()
            self._claimed.clear()

    def wanted(self):
        """Return whether a waiting pick has not had its approach planned yet."""
        with self._lock:
            return any(not slot.attempted for slot in self._pending.values())

    def next_to_plan(self, start, tolerance, token):
        """
        Return the oldest waiting pick whose approach is not planned from ``start``, or None.

        As (slot, pick): plan the leg from ``start`` and give it to :meth:`store` with the
        slot. Not planned from ``start``: never planned, or from further than ``tolerance``
        [m], or with settings other than ``token``.
        """
        with self._lock:
            for slot in self._pending.values():
                if not slot.fits(start, tolerance, token):
                    return slot, slot.pick
            return None

    def store(self, slot, start, token, approach):
        """
        Keep the approach planned for ``slot`` from ``start`` with ``token`` (None: it failed).

        Written into the slot, whether it still waits for its place, is claimed by its pair (a
        place that came while the leg was planned) or was dropped meanwhile (then nothing
        reaches it and the leg goes with it); counted as a leg in every case. A failed plan is
        not tried again from the same start (the pair's own plan reports the error).
        """
        with self._lock:
            self._counts['legs'] += 1
            slot.start, slot.token = np.array(start, dtype=float), token
            slot.approach, slot.attempted = approach, True

    def take(self, number, pick, start, tolerance, token):
        """
        Remove the slot of pair ``number``; return its approach if it fits the pair, else None.

        It fits when planned for ``pick`` exactly, with ``token`` and from within
        ``tolerance`` [m] of ``start`` (the rule of the release's start check: the motion
        then starts at the leg's start). Each call counts a hit or a miss: ask only for the
        pairs that could have had one.
        """
        with self._lock:
            slot = self._claimed.pop(number, None)
            hit = (slot is not None and slot.approach is not None
                   and np.array_equal(slot.pick, pick) and slot.fits(start, tolerance, token))
            self._counts['hits' if hit else 'misses'] += 1
            return slot.approach if hit else None


def _bound(slots, depth):
    """Drop the oldest of ``slots`` (an OrderedDict) beyond ``depth``."""
    while len(slots) > depth:
        slots.popitem(last=False)
