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
The path-space scan of the time-optimal profile: one greedy, jerk-limited scan along the arc.

A :class:`_Scanner` steps a :class:`_Scan` (states t, s, s', s'' and the jerk of each step)
forwards from T1 or, on the mirrored table, backwards from T2, taking the largest jerk legal
at both ends of each step; :mod:`~ellipath_ros.core.optimal_profile` runs two of them, joins
them and handles speed valleys, end speeds and the fallback. Every step counts against the
plan's step budget.

The loops run compiled (:func:`~ellipath_ros.core.compiled.kernel`): a scan is a few NumPy
arrays, and one kernel call runs it to its stopping condition (hundreds of steps), since a
Python call per step would cost as much as the step. The kernels do the float operations of
the plain-Python scan they replaced in the same order, so the plans are the same to the last
bit; their ``py_func`` is that plain form (test/test_arc_scan.py compares the two).

Layouts (all float64 unless said otherwise):

- table, shape (5, points): rows kappa [1/m], the rise of kappa to the next point, dkappa/ds
  [1/m**2], its rise, and the speed cap [m/s] of the cell starting at each point, on a
  uniform grid of ``points`` along the arc (the rises and caps of the last point are never
  read);
- constants, shape (_CONSTANTS,): the table's cell length [m], the speed, acceleration and
  jerk targets [m/s, m/s**2, m/s**3], their squares, the normal jerk share, and 2.0 (see
  :data:`_TWO`);
- factor, shape (points + 1,): per cell, the share of the acceleration target the back-ups
  left (1 until a back-up lowers it);
- budget, int64 shape (1,): the steps the plan may still take (shared by its two scanners);
- states, shape (6, capacity): rows t [s], s [m], s' [m/s], s'' [m/s**2] per state, the
  jerk s''' [m/s**3] of the step from each state to the next, and the highest index into
  ``factor`` the step to each state read (-1: none);
- info, int64 shape (6,): the number of states, the status, the back-ups so far, whether
  ``reading`` holds the table's reading at the last state, the number of states known (held
  from an earlier run of the scan, see :meth:`_Scanner.scan`: the steps up to there are
  taken as they stand), the lowest index into ``factor`` the scan's back-ups lowered;
- floats, shape (9,): the arc length at which the scan ends, then the reading (s, s', s'',
  kappa, dkappa/ds, cap, the middle and half width of the jerk range).
"""

import math
import struct

import numpy as np

from .compiled import kernel
from .limits import _ACCEL_MARGIN, _JERK_MARGIN, _SPEED_MARGIN

# Time step of the path-space scans [s]: the short one where the curvature (1/m) is above
# _SCAN_KAPPA, where the limits change fast along the path.
_SCAN_STEP = 1e-3
_SCAN_STEP_SHORT = 5e-4
_SCAN_KAPPA = 8.0
# ... and shorter still where the curvature changes by more than this share within a step
# (not below _SCAN_STEP_MIN).
_SCAN_KAPPA_CHANGE = 0.1
_SCAN_STEP_MIN = 2e-5
# Share of the jerk budget the scans give the normal component (3 kappa v a + kappa_s v**3),
# leaving the rest for changing the tangential acceleration. Handed to the kernels in the
# constants (read when a scanner is made), so that a study may change it.
_NORMAL_JERK_SHARE = 0.9
# Levelling off looks ahead by the distance it takes at least at this share of max_accel.
_LEVEL_REACH = 0.1
# A scan slowing down below this speed [m/s] stops (the other scan covers the rest).
_MIN_SCAN_SPEED = 1e-3
# Share of the jerk available in the state with which a scan ramps its acceleration down when
# it levels off at the speed limit.
_LEVEL_OFF_JERK = 0.9
# A scan that cannot follow a falling acceleration bound backs up this many steps and lowers
# its acceleration target by this factor over the troubled stretch, at most this often.
_BACK_UP_STEPS = 20
_BACK_UP_AHEAD = 5e-3
_BACK_UP_FACTOR = 0.75
_BACK_UP_LIMIT = 30

# A scan's status (info[_STATUS]): going on, reached its end, too fast for what lies ahead
# (the other scan covers it), gave up after _BACK_UP_LIMIT back-ups.
_LIVE, _END, _SPEED, _ACCEL = 0, 1, 2, 3
_STATUS_NAMES = ('live', 'end', 'speed', 'accel')
# What :func:`_advance` did: the scan stopped (see its status), took a step (or backed up),
# or the step budget ran out (the plan gives up on the scans).
_STOPPED, _ADVANCED, _OUT_OF_STEPS = 0, 1, -1
# Indices into a scan's info and floats, and into the constants.
_COUNT, _STATUS, _FAILURES, _READ, _KNOWN, _LOWERED = 0, 1, 2, 3, 4, 5
_END_AT, _READING = 0, 1
_CELL, _SPEED_TARGET, _ACCEL_TARGET, _JERK_TARGET = 0, 1, 2, 3
_ACCEL_SQUARED, _JERK_SQUARED, _SHARE, _TWO = 4, 5, 6, 7
_CONSTANTS = 8
# The states' row of the factor indices read, and info[_LOWERED] while no back-up lowered any.
_READS = 5
_NOT_LOWERED = 2 ** 62


# The key of a kept scan: its start (s, s', s''), the floats' bytes (-0.0 is not 0.0 in the
# states the scan records).
_THREE_FLOATS = struct.Struct('<3d')


class _NoMotion(Exception):
    """The scans found no motion for a stretch (the caller tries something slower)."""


@kernel
def _arc_tables(forward, backward):
    """
    Fill the tables (see the module's layouts) of the arc run forwards and backwards.

    ``forward`` (5, points) holds kappa, dkappa/ds and the cells' speed caps in its rows 0,
    2 and 4 (but the last point's cap) on entry; its other rows and ``backward`` (5, points)
    are filled. Backwards (from T2 to T1) the grid is reversed and dkappa/ds changes sign.
    """
    points = forward.shape[1]
    last = points - 1
    # Row by row (each a contiguous view): the loops index one dimension, not two.
    kappa_forward, rise_forward, kappa_s_forward, rise_s_forward, cap_forward = forward
    kappa_backward, rise_backward, kappa_s_backward, rise_s_backward, cap_backward = backward
    for index in range(points):
        kappa_backward[index] = kappa_forward[last - index]
        kappa_s_backward[index] = -kappa_s_forward[last - index]
    for index in range(last):
        rise_forward[index] = kappa_forward[index + 1] - kappa_forward[index]
        rise_s_forward[index] = kappa_s_forward[index + 1] - kappa_s_forward[index]
        rise_backward[index] = kappa_backward[index + 1] - kappa_backward[index]
        rise_s_backward[index] = kappa_s_backward[index + 1] - kappa_s_backward[index]
        cap_backward[index] = cap_forward[last - 1 - index]
    # The last point's rises and cap (never read) are 0.
    rise_forward[last] = rise_s_forward[last] = cap_forward[last] = 0.0
    rise_backward[last] = rise_s_backward[last] = cap_backward[last] = 0.0


class _Scanner:
    """
    The arc table, limits and back-up shares with which scans run along one direction.

    ``cell`` is the table's grid step [m]; ``budget`` is the step budget
    (int64 array of one value) shared with the plan's other scanner.

    The scans it hands out are kept for a later scan from the same state (see :meth:`scan`).
    A scan is done with once the scanner hands out the next one (the plan's stretches are
    solved one after another, and a stretch uses its scans before it splits).
    """

    __slots__ = ('table', 'constants', 'factor', 'budget', '_kept', '_handed', '_seeds')

    def __init__(self, table, cell, limits, budget):
        self.table = table
        self.budget = budget
        speed = limits.max_speed * _SPEED_MARGIN
        accel = limits.max_accel * _ACCEL_MARGIN
        jerk = limits.max_jerk * _JERK_MARGIN
        self.constants = np.array(
            [cell, speed, accel, jerk, accel ** 2, jerk ** 2, _NORMAL_JERK_SHARE, 2.0])
        self.factor = np.ones(table.shape[1] + 1)
        # The scans kept ({start key: scan}) and the one handed out last (or None).
        self._kept = {}
        self._handed = None
        # Steps taken elsewhere ({start key: (states, info)}, see keep).
        self._seeds = {}

    @property
    def cell(self):
        """Return the length [m] of one table cell."""
        return float(self.constants[_CELL])

    def parts(self):
        """Return the scanner as the kernels take it: (table, constants, factor, budget)."""
        return self.table, self.constants, self.factor, self.budget

    def scan(self, s, v, a, end):
        """
        Return a scan from (s, s', s'') to ``end``, with room for the budget's steps.

        A scan from that state handed out before is handed out again: its
        steps, taken on the same table and back-up shares, are what a new scan
        would take, and it takes them again as they stand (see
        :func:`_advance`), spending the budget as a new scan would. A back-up
        lowers the shares from one index of ``factor`` on: a kept scan's steps
        are known up to the first that read a share there (:meth:`_Scan.forget`).
        """
        handed = self._handed
        if handed is not None:
            lowered = int(handed.info[_LOWERED])
            if lowered != _NOT_LOWERED:
                for kept in self._kept.values():
                    kept.forget(lowered)
                for states, info in self._seeds.values():
                    _forget(states[_READS], info, lowered)
                handed.forget(lowered)
            self._kept[handed.key] = handed
        key = _THREE_FLOATS.pack(s, v, a)
        scan = self._kept.pop(key, None)
        if scan is None:
            scan = _Scan(s, v, a, end, max(int(self.budget[0]), 0) + 2, key)
            seed = self._seeds.pop(key, None)
            if seed is not None:
                known = int(seed[1][_KNOWN])
                scan.states[:, :known] = seed[0][:, :known]
                scan.info[_KNOWN] = known
        else:
            scan.restart(end)
        self._handed = scan
        return scan

    def keep(self, states, info):
        """
        Keep the states of a scan taken on this table elsewhere, for :meth:`scan`.

        ``states`` and ``info`` (layouts of a scan's) are those of a scan that
        took its steps on these constants with shares all 1 and no back-up (a
        probe's, see :func:`~ellipath_ros.core.optimal_profile._probe_scan`):
        the steps a scan from their first state takes while this scanner's
        shares are all 1, that is before it hands out a scan (none but its
        scans lower them). Kept only then, as they are (a new scan from that
        state copies them); a later back-up forgets them as any kept scan's.
        """
        if self._handed is None:
            self._seeds[_THREE_FLOATS.pack(states[1, 0], states[2, 0], states[3, 0])] = (
                states, info)

    def run(self, scan):
        """Advance ``scan`` until it stops; raise :class:`_NoMotion` if the budget runs out."""
        if _run(self.parts(), scan.parts()) == _OUT_OF_STEPS:
            raise _NoMotion()


class _Scan:
    """
    States (t, s, s', s'') of a greedy scan along the arc and the jerk of each step.

    ``t``, ``s``, ``v``, ``a`` have one entry per state, ``j`` one per step
    (views of the arrays the kernels fill). ``status`` is 'live', 'end'
    (reached ``end``), 'speed' (the speed became too high for what lies
    ahead: the other scan covers it) or 'accel' (gave up after
    ``_BACK_UP_LIMIT`` back-ups).
    """

    __slots__ = ('states', 'info', 'floats', 'key')

    def __init__(self, s, v, a, end, capacity, key):
        # Floats whatever the caller holds: one compiled signature (the warm-up's).
        self.states, self.info, self.floats = _new_scan(
            float(s), float(v), float(a), float(end), int(capacity))
        # Its start, _THREE_FLOATS.pack(s, v, a) (see _Scanner.scan).
        self.key = key

    def restart(self, end):
        """Start the scan again towards ``end``, the states it took known (see _Scanner.scan)."""
        info = self.info
        info[_COUNT], info[_STATUS], info[_FAILURES], info[_READ] = 1, _LIVE, 0, 0
        info[_LOWERED] = _NOT_LOWERED
        self.floats[_END_AT] = end

    def forget(self, lowered):
        """Keep the states known up to the first whose step read ``factor`` from ``lowered`` on."""
        _forget(self.states[_READS], self.info, lowered)

    def parts(self):
        """Return the scan as the kernels take it: (states, info, floats)."""
        return self.states, self.info, self.floats

    @property
    def count(self):
        """Return the number of states."""
        return int(self.info[_COUNT])

    @property
    def status(self):
        """Return why the scan stopped, or 'live'."""
        return _STATUS_NAMES[self.info[_STATUS]]

    t = property(lambda self: self.states[0, :self.count], doc='Time of each state [s].')
    s = property(lambda self: self.states[1, :self.count], doc='Arc length [m].')
    v = property(lambda self: self.states[2, :self.count], doc="Speed s' [m/s].")
    a = property(lambda self: self.states[3, :self.count], doc="s'' [m/s**2].")
    j = property(lambda self: self.states[4, :self.count - 1], doc='Jerk of each step.')

    def last(self):
        """Return the last state (t, s, s', s'') as floats."""
        return tuple(self.states[:4, self.count - 1].tolist())

    def state(self, time):
        """Return (s, s', s'') at ``time`` (clamped to the scan)."""
        return _state(self.states, self.count, time)

    def time_at(self, s_query):
        """Return the time at which the scan reaches ``s_query`` (within its range)."""
        return _time_at(self.states, self.count, s_query)

    def rows(self, time):
        """Return the pieces (duration, s, s', s'', s''') from the start to ``time``."""
        return _rows(self.states, self.count, time)

    def reversed_rows(self, time, length):
        """Return the forward-time pieces of a backward scan from ``time`` back to its start."""
        return _reversed_rows(self.states, self.count, time, length)


# -- the kernels ------------------------------------------------------------------------------

@kernel
def _py_max(first, second):
    """
    Return Python's ``max(first, second)`` of two floats: the first unless the second is greater.

    Its choice with NaN and signed zeros, which the compiled builtin need not share.
    """
    return second if second > first else first


@kernel
def _py_min(first, second):
    """
    Return Python's ``min(first, second)`` of two floats: the first unless the second is less.

    See :func:`_py_max`.
    """
    return second if second < first else first


@kernel
def _new_scan(s, v, a, end, capacity):
    """Return the (states, info, floats) of a scan from (s, s', s'') to ``end`` [m]."""
    states = np.empty((6, capacity))
    states[0, 0], states[1, 0], states[2, 0], states[3, 0] = 0.0, s, v, a
    states[_READS, 0] = -1.0
    info = np.zeros(6, dtype=np.int64)
    info[_COUNT] = info[_KNOWN] = 1
    info[_LOWERED] = _NOT_LOWERED
    floats = np.zeros(9)
    floats[_END_AT] = end
    return states, info, floats


@kernel
def _forget(reads, info, lowered):
    """
    Cut info[_KNOWN] to the first state whose step read ``factor`` from ``lowered`` on.

    ``reads`` is the states' row of the highest factor index each step read
    (:data:`_READS`); the first state has no step. One kernel call where a
    NumPy comparison, search and two conversions cost a few microseconds per
    kept scan, for each scan a scanner hands out after a back-up.
    """
    for index in range(1, info[_KNOWN]):
        if reads[index] >= lowered:
            info[_KNOWN] = index
            return


@kernel
def _bisect_right(values, count, x):
    """Return ``bisect.bisect_right(values[:count], x)`` (values ascending)."""
    low, high = 0, count
    while low < high:
        middle = (low + high) // 2
        if x < values[middle]:
            high = middle
        else:
            low = middle + 1
    return low


@kernel(zero_divisions=False)
def _table_at(table, cell, s):
    """
    Return (kappa [1/m], dkappa/ds [1/m**2], speed cap [m/s]) at arc length ``s`` [m].

    Interpolated linearly within the cell (extrapolated past the ends); ``cell`` is
    the grid step [m].
    """
    x = s / cell
    index = int(x)
    last = table.shape[1] - 2
    if index < 0:
        index = 0
    elif index > last:
        index = last
    fraction = x - index
    return (table[0, index] + fraction * table[1, index],
            table[2, index] + fraction * table[3, index], table[4, index])


@kernel
def _jerk_range(table, constants, s, v, a):
    """
    Return (found, lowest, highest): the s''' range keeping |jerk| <= target at (s, v, a).

    |jerk|**2 = (s''' - kappa**2 v**3)**2 + (kappa_s v**3 + 3 kappa v a)**2; ``found``
    is False (and the range 0) where the normal part alone exceeds the target.
    """
    kappa, kappa_s, _ = _table_at(table, constants[_CELL], s)
    v3 = v * v * v
    normal = kappa_s * v3 + 3.0 * kappa * v * a
    if abs(normal) >= constants[_JERK_TARGET]:
        return False, 0.0, 0.0
    room = math.sqrt(constants[_JERK_SQUARED] - normal * normal)
    return True, kappa * kappa * v3 - room, kappa * kappa * v3 + room


@kernel(zero_divisions=False)
def _level_off(v, a, speed, h, level, jerk_limit):
    """Return (jerk, step): constant jerk bringing s'' to 0 exactly at s' = ``speed``."""
    gap = speed - v
    jerk = -level if gap <= 0.0 else _py_max(-a * a / (2.0 * gap), -jerk_limit)
    return jerk, _py_min(h, a / -jerk)


@kernel(inline=True)
def _until_level_off(v, a, jerk, h, speed, level):
    """
    Return the time within the step at which v + a**2/(2 level) reaches ``speed``.

    40 bisections of [0, h], two per pass: the middle and both middles the
    next bisection may take are tried together (:func:`_levels_off_by`), so
    that the next pass does not wait for the outcome of this one (a branch
    the processor guesses half the time wrong); the same trials, the same
    bracket after each pass, a fifth of the time.
    """
    low, high, twice_level = 0.0, h, 2.0 * level
    for _ in range(20):
        x = 0.5 * (low + high)
        x_low, x_high = 0.5 * (low + x), 0.5 * (x + high)
        over = _levels_off_by(v, a, jerk, x, speed, twice_level)
        over_low = _levels_off_by(v, a, jerk, x_low, speed, twice_level)
        over_high = _levels_off_by(v, a, jerk, x_high, speed, twice_level)
        if over:
            if over_low:
                high = x_low
            else:
                low, high = x_low, x
        elif over_high:
            low, high = x, x_high
        else:
            low = x_high
    return low


@kernel(inline=True)
def _levels_off_by(v, a, jerk, x, speed, twice_level):
    """Return whether v + a**2/(2 level) passes ``speed`` at time ``x`` of the step."""
    jerk_x = jerk * x
    a1 = a + jerk_x
    return v + x * (a + jerk_x / 2.0) + a1 * a1 / twice_level > speed


@kernel(inline=True)
def _held(done, table, constants, factor, budget, states, info, floats):
    """
    Return ``done``: the one return of :func:`_advance` and :func:`_stop_or_back_up`.

    Inlined into a loop, a kernel takes its arrays as new variables, each counted: an atomic
    increment where the kernel starts, a decrement where the variable dies. LLVM's pass that
    drops such pairs (numba's refprune) drops one across blocks only where the decrement
    follows every path from the increment and no other decrement lies between. Arrays dying
    at their last uses, scattered along the step's returns, kept all seven pairs: 14 atomic
    operations per step, 15 % of the arc solve's CPU (perf, issue 11). Used together here,
    at the one return, they die together there, and every pair is dropped; the loops that
    inline the step compile without raising divisions (``zero_divisions=False``: the step's
    divisors are the cell, the levelling jerk, the step, 3 kappa v where kappa v > 0), as an
    exception's way out would pass by the decrements too.
    """
    return done


@kernel(inline=True)
def _advance(table, constants, factor, budget, states, info, floats, back_up):
    """
    Take one step of a scan: _ADVANCED, _STOPPED (see its status) or _OUT_OF_STEPS.

    The scanner's arrays (table, constants, factor, budget), then the scan's
    (states, info, floats), each passed on its own: a kernel looping over
    steps unpacks its tuples once, and the step is this kernel's own code,
    with one return past every array's last use, so that no array is counted
    per step (see :func:`_held`). The step takes the largest jerk within the
    jerk norm at the state whose end state stays below the acceleration
    target there (see the comment in the loop), levels off before the speed
    limit ahead, and is legal at its end (else the largest legal jerk,
    bisected towards the lowest). The new state is appended with the table's
    reading there, which the next step starts from. A step that cannot be
    taken stops the scan or backs it up (:func:`_stop_or_back_up`).
    """
    done, failure = _STOPPED, _LIVE
    count = info[_COUNT]
    # Whether the step is still being taken: False once it stops, runs out or fails.
    going = info[_STATUS] == _LIVE
    if going and states[1, count - 1] >= floats[_END_AT]:
        info[_STATUS] = _END
        going = False
    if going:
        budget[0] -= 1
        # A scan holds at most the budget's steps (see _Scanner.scan): the capacity test only
        # guards the arrays.
        if budget[0] < 0 or count >= states.shape[1]:
            done, going = _OUT_OF_STEPS, False
        elif count < info[_KNOWN]:
            # The step this scan took from here before (see _Scanner.scan), taken again as it
            # stands: the same state, spending the same step of the budget. The next step
            # reads the table afresh, which gives what the reading carried over gives.
            info[_COUNT] = count + 1
            info[_READ] = 0
            done, going = _ADVANCED, False
    cell, speed = constants[_CELL], constants[_SPEED_TARGET]
    accel_limit, jerk_limit = constants[_ACCEL_TARGET], constants[_JERK_TARGET]
    accel_squared, jerk_squared = constants[_ACCEL_SQUARED], constants[_JERK_SQUARED]
    last = table.shape[1] - 2
    # The factors' last index (they cover the table's points and one beyond).
    last_factor = table.shape[1]
    s = v = a = kappa = kappa_s = cap = middle = room = 0.0
    if going and info[_READ] == 0:
        s, v, a = states[1, count - 1], states[2, count - 1], states[3, count - 1]
        kappa, kappa_s, cap = _table_at(table, cell, s)
        # The jerk range at (s, v, a): |jerk|**2 = (s''' - kappa**2 v**3)**2
        # + (kappa_s v**3 + 3 kappa v a)**2, the middle of the range kappa**2 v**3.
        v3 = v * v * v
        normal = kappa_s * v3 + 3.0 * kappa * v * a
        if normal >= jerk_limit or -normal >= jerk_limit:
            failure, going = _SPEED, False
        else:
            middle, room = kappa * kappa * v3, math.sqrt(jerk_squared - normal * normal)
    elif going:
        # The previous step read the table at this state (and found its jerk range).
        s, v, a = floats[_READING], floats[_READING + 1], floats[_READING + 2]
        kappa, kappa_s, cap = floats[_READING + 3], floats[_READING + 4], floats[_READING + 5]
        middle, room = floats[_READING + 6], floats[_READING + 7]
    if cap < speed:
        speed = cap
    if going and (v > speed * (1.0 + 1e-9) or (a < 0.0 and v < _MIN_SCAN_SPEED)):
        failure, going = _SPEED, False
    lowest, highest = middle - room, middle + room
    # Whether the table's reading at the step's end (s_end, v_end, kappa_end, kappa_s_end,
    # cap_end) is that of the jerk and step chosen.
    read = False
    s_end = v_end = kappa_end = kappa_s_end = cap_end = 0.0
    jerk = h = 0.0
    # The highest factor index read (see _Scanner.scan).
    reads = -1
    if going:
        h = _SCAN_STEP if kappa <= _SCAN_KAPPA else _SCAN_STEP_SHORT
        if v * abs(kappa_s) * h > _SCAN_KAPPA_CHANGE * kappa:
            # The curvature changes fast here (a needle-sharp bend): shorter steps.
            h = _py_max(_SCAN_KAPPA_CHANGE * kappa / (v * abs(kappa_s)), _SCAN_STEP_MIN)
        # Levelling off ramps s'' down with a share of the jerk the state leaves for it.
        level = 1e-3 * jerk_limit
        if -lowest >= level:
            level = -lowest
        level *= _LEVEL_OFF_JERK
        # Level off (and cruise) at the lowest speed limit until where the levelling off
        # would end.
        reach = _LEVEL_REACH * accel_limit
        if a >= reach:
            reach = a
        reach = v * reach / level
        goal = speed
        for ahead in (s + 0.5 * reach, s + reach):
            index = int(ahead / cell)
            if index < 0:
                index = 0
            elif index > last:
                index = last
            if table[4, index] < goal:
                goal = table[4, index]
        if a <= 1e-12 and v >= goal * (1.0 - 1e-9):
            jerk, a = 0.0, 0.0
            # Cruising changes nothing but the place: up to half a table cell per step.
            h = _py_max(h, 0.5 * cell / v)
        elif a > 0.0 and v + a * a / (2.0 * level) >= goal * (1.0 - 1e-12):
            jerk, h = _level_off(v, a, goal, h, level, jerk_limit)
        else:
            normal_share = constants[_SHARE]
            half_a = a / 2.0
            jerk = highest
            for _ in range(12):
                h_jerk = h * jerk
                s_end = s + h * (v + h * (half_a + h_jerk / 6.0))
                v_end = v + h * (a + h_jerk / 2.0)
                x = s_end / cell
                cell_index = int(x)
                index = cell_index
                if index < 0:
                    index = 0
                elif index > last:
                    index = last
                fraction = x - index
                kappa_end = table[0, index] + fraction * table[1, index]
                kappa_s_end = table[2, index] + fraction * table[3, index]
                cap_end = table[4, index]
                # The largest s'' to aim at in the end state (none if v is too high there).
                # Below the acceleration norm, and such that the normal jerk
                # 3 kappa v s'' + kappa_s v**3 leaves a share of the jerk budget for changing
                # s'' (with s''' = 0 feasible: the tangential part of p''' v**3 is
                # -kappa**2 v**3). Negative where the curvature tightens too fast for the
                # speed: the scan then slows down. A back-up lowers it (factors of 1 change
                # no target: 1.0 * target and target - 0.0 * accel_limit are target).
                has_target = False
                target = 0.0
                kappa_v = kappa_end * v_end
                normal_accel = kappa_v * v_end
                # math.pow, the C library's pow that Python's ** calls (not v * v * v, which
                # rounds differently).
                v_cubed = math.pow(v_end, 3.0)
                centripetal = kappa_end * kappa_end * v_cubed
                if (v_end > 0.0 and v_end <= cap_end * (1.0 + 1e-9)
                        and normal_accel < accel_limit and centripetal < jerk_limit):
                    target = math.sqrt(accel_squared - normal_accel * normal_accel)
                    floor = -target
                    if kappa_v > 0.0:
                        share = normal_share * math.sqrt(
                            jerk_squared - math.pow(centripetal, constants[_TWO]))
                        change = kappa_s_end * v_cubed
                        divisor = 3.0 * kappa_end * v_end
                        bound = (share - change) / divisor
                        if bound < target:
                            target = bound
                        bound = (-share - change) / divisor
                        if bound > floor:
                            floor = bound
                    share_index = (0 if cell_index < 0 else last_factor
                                   if cell_index > last_factor else cell_index)
                    if share_index > reads:
                        reads = share_index
                    target_share = factor[share_index]
                    target = (target_share * target if target > 0.0
                              else target - (1.0 - target_share) * accel_limit)
                    has_target = target >= floor
                if not has_target:
                    # Too fast at the step's end: try less jerk (down to the lowest).
                    if jerk <= lowest + 1e-9:
                        failure, going = _SPEED, False
                        break
                    jerk = 0.5 * (jerk + lowest)
                    continue
                if a + h_jerk <= target + 1e-12:
                    read = True
                    break
                jerk = (target - a) / h
            if going:
                a1, v1 = a + jerk * h, v + h * (a + h * jerk / 2.0)
                if a1 > 0.0 and v1 + a1 * a1 / (2.0 * level) > goal:
                    read = False
                    h = _until_level_off(v, a, jerk, h, goal, level)
                    if h <= 1e-12:
                        jerk, h = _level_off(v, a, goal, _SCAN_STEP_SHORT, level, jerk_limit)
                elif a > 0.0 > a1 and v - a * a / (2.0 * jerk) > goal:
                    # s'' passes 0 inside the step: its speed peak must stay below the limit
                    # too.
                    read = False
                    jerk, h = _level_off(v, a, goal, h, level, jerk_limit)
    if going and not jerk >= lowest - 1e-9:
        # Not accelerating, the speed itself is too high for what follows.
        failure, going = _ACCEL if a > 1e-9 else _SPEED, False
    if going:
        # The jerk must be legal at the step's end too; if it is not, the largest legal one
        # in [lowest, jerk] is bisected for (12 halvings).
        low, high, legal, trial = lowest, jerk, False, jerk
        legal_jerk = 0.0
        for halving in range(13):
            if not read:
                s_end = s + h * (v + h * (a / 2.0 + h * trial / 6.0))
                v_end = v + h * (a + h * trial / 2.0)
                kappa_end, kappa_s_end, cap_end = _table_at(table, cell, s_end)
            read = False
            a_end = a + h * trial
            v3 = v_end * v_end * v_end
            normal = kappa_s_end * v3 + 3.0 * kappa_end * v_end * a_end
            if normal < jerk_limit and -normal < jerk_limit:
                room_end = math.sqrt(jerk_squared - normal * normal)
                middle_end = kappa_end * kappa_end * v3
                if middle_end - room_end - 1e-9 <= trial <= middle_end + room_end + 1e-9:
                    legal, legal_jerk = True, trial
                    floats[_READING], floats[_READING + 1] = s_end, v_end
                    floats[_READING + 2], floats[_READING + 3] = a_end, kappa_end
                    floats[_READING + 4], floats[_READING + 5] = kappa_s_end, cap_end
                    floats[_READING + 6], floats[_READING + 7] = middle_end, room_end
                    if halving == 0:
                        break
                    low = trial
                    trial = 0.5 * (low + high)
                    continue
            high = trial
            trial = 0.5 * (low + high)
        if legal:
            states[0, count] = states[0, count - 1] + h
            states[1, count], states[2, count], states[3, count] = (
                floats[_READING], floats[_READING + 1], floats[_READING + 2])
            states[4, count - 1] = legal_jerk
            states[_READS, count] = reads
            info[_COUNT] = info[_KNOWN] = count + 1
            info[_READ] = 1
            done = _ADVANCED
        else:
            failure = _ACCEL if a > 1e-9 else _SPEED
    if failure != _LIVE:
        done = _stop_or_back_up(failure, table, constants, factor, budget, states, info, floats,
                                back_up)
    return _held(done, table, constants, factor, budget, states, info, floats)


@kernel(inline=True)
def _stop_or_back_up(failure, table, constants, factor, budget, states, info, floats,
                     back_up):
    """
    Stop a scan whose step failed (``failure``: _SPEED or _ACCEL), or back it up.

    Returns _STOPPED (the status says why) or _ADVANCED. Where the
    acceleration bound falls faster than the jerk can follow (_ACCEL), the
    scan backs up ``_BACK_UP_STEPS`` and lowers its acceleration target over
    the stretch (lower again on repeated trouble), unless ``back_up`` is
    False or it did so ``_BACK_UP_LIMIT`` times already. The arrays are
    :func:`_advance`'s; one return, past every array's last use (see :func:`_held`).
    """
    done = _STOPPED
    if failure == _SPEED or info[_FAILURES] >= _BACK_UP_LIMIT or not back_up:
        info[_STATUS] = failure
    else:
        info[_FAILURES] += 1
        last = info[_COUNT] - 1
        first = max(0, last - _BACK_UP_STEPS)
        cell = constants[_CELL]
        low = max(int(states[1, first] / cell), 0)
        high = min(int((states[1, last] + _BACK_UP_AHEAD) / cell) + 1, factor.size)
        # A share of the stretch's lowest is below every share in it: all become that.
        lowest = factor[low]
        for index in range(low + 1, high):
            lowest = _py_min(lowest, factor[index])
        # Element by element: a slice would be one more counted array.
        lowest *= _BACK_UP_FACTOR
        if low < info[_LOWERED]:
            info[_LOWERED] = low
        for index in range(low, high):
            factor[index] = lowest
        # The states past the last one kept are no longer this scan's.
        info[_COUNT] = info[_KNOWN] = first + 1
        info[_READ] = 0
        done = _ADVANCED
    return _held(done, table, constants, factor, budget, states, info, floats)


@kernel(zero_divisions=False)
def _run(scanner, scan):
    """Advance ``scan`` until it stops: _STOPPED, or _OUT_OF_STEPS."""
    table, constants, factor, budget = scanner
    states, info, floats = scan
    while True:
        done = _advance(table, constants, factor, budget, states, info, floats, True)
        if done != _ADVANCED:
            return done


@kernel
def _speed_at(states, count, s_query):
    """Return (found, s' at ``s_query``) interpolated between the first ``count`` states."""
    position = _bisect_right(states[1], count, s_query)
    if position == 0 or position >= count:
        return False, 0.0
    low, high = states[1, position - 1], states[1, position]
    x = (s_query - low) / (high - low) if high > low else 0.0
    return True, states[2, position - 1] + x * (states[2, position] - states[2, position - 1])


@kernel
def _state(states, count, time):
    """Return (s, s', s'') at ``time`` [s] of a scan with ``count`` states (clamped to it)."""
    steps = count - 1
    index = min(max(_bisect_right(states[0], count, time) - 1, 0), max(steps - 1, 0))
    if steps == 0:
        return states[1, 0], states[2, 0], states[3, 0]
    x = time - states[0, index]
    v, a, j = states[2, index], states[3, index], states[4, index]
    return (states[1, index] + x * (v + x * (a / 2.0 + x * j / 6.0)),
            v + x * (a + x * j / 2.0), a + x * j)


@kernel
def _time_at(states, count, s_query):
    """Return the time [s] at which a scan with ``count`` states reaches ``s_query`` [m]."""
    t, s, v, a, j = states[0], states[1], states[2], states[3], states[4]
    if count == 1:
        return t[0]
    last = count - 2
    index = min(max(_bisect_right(s, count, s_query) - 1, 0), last)
    low, high = t[index], t[min(index + 1, count - 1)]
    # Bisection on the position, each piece evaluated as _state does (same piece, same
    # arithmetic); it stops once the middle no longer moves.
    middle = 0.5 * (low + high)
    for _ in range(60):
        piece = min(max(_bisect_right(t, count, middle) - 1, 0), last)
        x = middle - t[piece]
        if s[piece] + x * (v[piece] + x * (a[piece] / 2.0 + x * j[piece] / 6.0)) < s_query:
            low = middle
        else:
            high = middle
        previous, middle = middle, 0.5 * (low + high)
        if middle == previous:
            break
    return middle


@kernel
def _rows(states, count, time):
    """
    Return the pieces from the start to ``time`` [s], shape (pieces, 5).

    Each row: duration [s], s, s', s'', s''' at its start.
    """
    rows = np.empty((count - 1, 5))
    pieces = 0
    for index in range(count - 1):
        if states[0, index] >= time:
            break
        rows[pieces, 0] = _py_min(states[0, index + 1], time) - states[0, index]
        rows[pieces, 1:] = states[1:5, index]
        pieces += 1
    return rows[:pieces]


@kernel
def _reversed_rows(states, count, time, length):
    """
    Return the forward-time pieces of a backward scan from ``time`` back to its start.

    Shape (pieces, 5), rows as :func:`_rows`'; ``length`` [m] is the arc's.
    """
    rows = np.empty((count, 5))
    index = min(max(_bisect_right(states[0], count, time) - 1, 0), count - 2)
    s, v, a = _state(states, count, time)
    pieces = 0
    if time > states[0, index]:
        rows[0, 0], rows[0, 1], rows[0, 2] = time - states[0, index], length - s, v
        rows[0, 3], rows[0, 4] = -a, states[4, index]
        pieces = 1
    for index in range(index - 1, -1, -1):
        rows[pieces, 0] = states[0, index + 1] - states[0, index]
        rows[pieces, 1] = length - states[1, index + 1]
        rows[pieces, 2], rows[pieces, 3] = states[2, index + 1], -states[3, index + 1]
        rows[pieces, 4] = states[4, index]
        pieces += 1
    return rows[:pieces]
