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
The knot search: few joint knots whose JTC interpolation follows the planned TCP path.

:func:`minimal_knots` places knots on a planned motion's samples
(:class:`~ellipath_ros.core.joint_trajectory.MotionSamples`) such that the quintic that
ros2_control's joint_trajectory_controller (JTC) interpolates between them
(:func:`~ellipath_ros.core.joint_trajectory.quintic_interpolate`), mapped through forward
kinematics, stays within a tolerance of the planned TCP position on a check grid of every
segment; :func:`segment_deviations` measures that deviation for given knots. The search
(refine, re-place by error density, prune) is one compiled call, :func:`_search_knots`, run
again where it needs the motion at times no sample gives.

Arrays: times have shape (K,) [s]; positions, velocities and accelerations (K, 3)
[rad, rad/s, rad/s^2], column i for arm i.
"""

import math

from ellipath_ros.core.compiled import kernel
from ellipath_ros.core.errors import InvalidInputError
from ellipath_ros.core.errors import require_range
from ellipath_ros.core.joint_trajectory import _checked_state_at
from ellipath_ros.core.joint_trajectory import _fill_quintic
from ellipath_ros.core.joint_trajectory import _hermite_in
from ellipath_ros.core.joint_trajectory import _joint_motion_at
from ellipath_ros.core.joint_trajectory import _motion_duration
from ellipath_ros.core.joint_trajectory import _names
from ellipath_ros.core.joint_trajectory import _nearest_samples
from ellipath_ros.core.joint_trajectory import _polynomial
from ellipath_ros.core.joint_trajectory import _SAFETY
from ellipath_ros.core.joint_trajectory import _SAME_TIME
from ellipath_ros.core.joint_trajectory import _sorted_position
from ellipath_ros.core.joint_trajectory import DEFAULT_JOINT_NAMES
from ellipath_ros.core.joint_trajectory import JointTrajectoryData
from ellipath_ros.core.joint_trajectory import MotionSamples
from ellipath_ros.core.kinematics import _ASSEMBLED
from ellipath_ros.core.kinematics import _forward_point
from ellipath_ros.core.kinematics import _kernel_geometry
from ellipath_ros.core.kinematics import joint_trig_motion
import numpy as np

__all__ = ['minimal_knots', 'segment_deviations']

# First guess of the knot spacing [s]; refinement and pruning fix it where needed.
_INITIAL_STEP = 0.05
# Trials of error-density re-placement after the first refine-and-prune search.
_REPLACEMENTS = 6
# The knot search checks against a table of planned positions built on the motion's samples
# (MotionSamples), for tolerances from this one up [m]; below, the motion is evaluated at
# every check point.
_PLANNED_TABLE_MIN_TOLERANCE = 1e-5


def minimal_knots(motion, geometry, joint_names=DEFAULT_JOINT_NAMES, tolerance=1e-4, *,
                  check_samples=24, min_interval=1e-6, samples=None):
    """
    Few knots whose JTC quintic interpolation follows the planned TCP path within tolerance.

    Each knot carries the exact joint position, velocity and acceleration of the motion at
    its time. A segment is accepted when, on a grid of ``check_samples`` interior points, the
    forward kinematics of JTC's quintic interpolation deviates from the planned TCP position
    by at most 0.95 ``tolerance`` (margin for peaks between grid points). Search:

    1. refine: start from knots about 50 ms apart; split every rejected segment in half
       (one vectorised evaluation per round) until all are accepted;
    2. re-place: halving leaves knots on a dyadic lattice, so try fewer knots spread evenly
       over the measured error density (quintic error ~ h^6, see ``_equidistributed``); a
       trial set replaces the current one only if all its segments pass, and is then
       pruned (3.). At most six trials;
    3. prune: test, for every interior knot at once, the segment that would replace it and
       its two neighbours; drop the acceptable ones with the smallest errors, never two
       adjacent knots in one round; repeat until no knot can be dropped. A refined set that
       no trial replaced is pruned at the end.

    The result is locally minimal (no single knot can be removed), includes t = 0 and
    t = duration, and is typically within one or two knots of the greedy optimum. Knots sit
    on the motion's samples (:class:`MotionSamples`) nearest to where the search wants them,
    so the search evaluates the motion only where no sample is near. The search is one
    compiled call (:func:`_search_knots`); where it needs the motion at a time that no
    sample gives, it stops, the motion is evaluated there, and it goes on from the step
    where it stopped.

    Parameters
    ----------
    motion : Motion
        The planned TCP motion.
    geometry : DeltaGeometry
        Robot dimensions and joint position limits.
    joint_names : sequence of str
        Names of the three joints, arm 0, 1, 2.
    tolerance : float
        Largest allowed TCP deviation [m], > 0.
    check_samples : int
        Interior check points per segment, >= 20.
    min_interval : float
        Shortest allowed knot interval [s]; the search gives up below it.
    samples : MotionSamples, optional
        The motion's samples (``MotionSamples.of(motion, geometry)`` when omitted).

    Returns
    -------
    tuple of (JointTrajectoryData, float)
        The knots, and the largest TCP deviation found on the check grids of the final
        segments [m].

    Raises
    ------
    UnreachableError
        A knot or check point is outside the workspace or at a singularity.
    InvalidInputError
        The tolerance cannot be met with knots at least ``min_interval`` apart.

    """
    names = _names(joint_names)
    duration = _motion_duration(motion)
    accept = _SAFETY * require_range('tolerance', tolerance, 0.0, low_open=True, unit='m')
    check_count = int(require_range('check_samples', check_samples, 20.0))
    shortest = require_range('min_interval', min_interval, 0.0, low_open=True, unit='s')
    fractions = np.arange(1, check_count + 1) / (check_count + 1.0)

    samples = MotionSamples.of(motion, geometry) if samples is None else samples
    source = _sample_source(samples)
    table = _planned_table(samples, accept)
    initial = np.linspace(0.0, duration, max(2, math.ceil(duration / _INITIAL_STEP)) + 1)
    evaluated = _Evaluated()
    # The starting knots no sample serves, evaluated before the search instead of in a rerun
    # after its first stop: the states it would stop for (on 376 curvature legs, 165 first
    # runs stopped there).
    low, high = _cells(initial)
    missing = ~samples._nearest(initial, low, high)[1]
    if missing.any():
        wanted = initial[missing]
        evaluated.add_states(wanted, _motion_states(samples, wanted))
    arms = _kernel_geometry(geometry)[:5]
    journal, checkpoint = np.empty(0), _START
    while True:
        (status, times, q, qdot, qddot, error, checkpoint, wanted, low, high,
         journal) = _search_knots(initial, source, evaluated.states, table, evaluated.planned,
                                  arms, fractions, accept, shortest, journal, checkpoint)
        if not evaluated.supplied(status, samples, wanted):
            break
    if status == _TOO_FINE:
        raise InvalidInputError(
            f'tolerance: expected a tolerance the motion can meet with knots at least '
            f'{shortest:g} s apart, got {accept / _SAFETY:g} m (error '
            f'{low[0]:.3g} m left near t={wanted[0]:.6g} s)')
    if status == _NOT_FINITE:
        raise InvalidInputError(
            f'knots: expected finite interpolation errors, got {error} (motion out of reach '
            'between samples?)')
    return JointTrajectoryData(names, times, q, qdot, qddot), error


def segment_deviations(samples, trajectory, segments, tolerance, check_samples=24):
    """
    Return the largest TCP deviation [m] (S,) of JTC's quintic on each of ``segments``.

    Checked as :func:`minimal_knots` checks a segment: on ``check_samples`` even interior
    points, against the planned positions interpolated from ``samples``' table
    (:meth:`MotionSamples.planned_table`), or, for a ``tolerance`` below the table's
    resolution, evaluated from the motion. A pose that cannot be assembled counts as inf.

    Parameters
    ----------
    samples : MotionSamples
        The samples of the motion that ``trajectory`` follows.
    trajectory : JointTrajectoryData
        Points on the motion (exact joint states at their times).
    segments : numpy.ndarray
        Indices (S,) of the segments (point i to i + 1) to check.
    tolerance : float
        The tolerance the deviations are for [m] (chooses the table or the motion).
    check_samples : int
        Interior check points per segment.

    Returns
    -------
    numpy.ndarray
        The deviations (S,) [m].

    """
    segments = np.asarray(segments, dtype=np.int64)
    fractions = np.arange(1, check_samples + 1) / (check_samples + 1.0)
    knots = tuple(np.require(values, float, ('C', 'W')) for values in (
        trajectory.time_from_start, trajectory.positions, trajectory.velocities,
        trajectory.accelerations))
    geometry = _kernel_geometry(samples.geometry)[:5]
    table = _planned_table(samples, _SAFETY * tolerance)
    planned = (np.empty(0), np.empty((0, 3)))
    while True:
        status, deviations, need = _deviations_of(knots, segments, table, planned, geometry,
                                                  fractions)
        if status != _NEEDS_PLANNED:
            return deviations
        # Below the table's resolution: the motion at the check times the kernel asked for.
        planned = _merged_rows(planned, (need[0], _checked_state_at(samples.motion,
                                                                    need[0])[0]))


def _split_segments(samples, trajectory, steps, segments, tolerance, gap, halvings,
                    check_samples=24):
    """
    Return ``trajectory`` with points splitting ``segments``, and the new segments' deviation.

    Each of ``segments`` (S,) (point i to i + 1) gets a point at each of the sorted times
    ``steps`` inside it (not within ``gap`` of its ends), or, if it has none, at its middle:
    the sample nearest to the middle if that lies in the middle half of the segment, else the
    middle itself. A point closer than ``gap`` to a point or to one added before it (in time
    order) is left out; the others sit on the sample at their time, or take the motion's
    state there (:meth:`MotionSamples.states`). Every segment with an end not among
    ``trajectory``'s points is then checked as :func:`minimal_knots` checks its own
    (:func:`segment_deviations`, accepted up to ``_SAFETY`` of ``tolerance``); those that
    fail get a point at their middle in the same way, up to ``halvings`` times. One
    compiled call (:func:`_split_points`), run again where it needs the motion at times no
    sample gives.

    Parameters
    ----------
    samples : MotionSamples
        The samples of the motion that ``trajectory`` follows.
    trajectory : JointTrajectoryData
        Points on the motion (exact joint states at their times).
    steps : numpy.ndarray
        Sorted times (N,) [s] at which the segments are split where they hold one.
    segments : numpy.ndarray
        Indices (S,) of the segments to split, sorted.
    tolerance : float
        Largest allowed TCP deviation [m].
    gap : float
        Shortest distance of an added point from any other [s].
    halvings : int
        Rounds of halving the new segments that fail the check.
    check_samples : int
        Interior check points per segment.

    Returns
    -------
    tuple of (JointTrajectoryData, float)
        The points, and the largest deviation on the new segments [m] (0 with none; inf if
        one still fails after the halvings).

    """
    accept = _SAFETY * tolerance
    fractions = np.arange(1, check_samples + 1) / (check_samples + 1.0)
    source = _sample_source(samples)
    table = _planned_table(samples, accept)
    geometry = _kernel_geometry(samples.geometry)[:5]
    knots = (trajectory.time_from_start, trajectory.positions, trajectory.velocities,
             trajectory.accelerations)
    same = _SAME_TIME * samples.duration
    evaluated = _Evaluated()
    while True:
        status, times, q, qdot, qddot, deviation, need = _split_points(
            knots, steps, segments, source, evaluated.states, table, evaluated.planned,
            geometry, fractions, accept, gap, halvings, same)
        if not evaluated.supplied(status, samples, need[0]):
            return JointTrajectoryData(trajectory.joint_names, times, q, qdot, qddot), deviation


def _sample_source(samples):
    """Return the samples' (times, cos q, sin q, q_dot, q_ddot) that the kernels place on."""
    # C-contiguous and writeable: the one array type the kernels are compiled for.
    return tuple(np.require(values, float, ('C', 'W')) for values in (
        samples.times, samples.cos_q, samples.sin_q, samples.qdot, samples.qddot))


@kernel
def _split_points(knots, steps, segments, source, evaluated, table, planned, geometry,
                  fractions, accept, gap, halvings, same):
    """
    Return :func:`_split_segments`' points: (status, times, q, q_dot, q_ddot, deviation, need).

    ``knots`` the points (times, q, q_dot, q_ddot), ``source``, ``evaluated``, ``table``,
    ``planned`` and ``geometry`` as for :func:`_search_knots`, ``same`` the largest distance
    [s] of a sample from a point that sits on it. Stops as :func:`_search_knots` does, with
    ``_NEEDS_STATES`` (wanted times (a), empty cells (b, c)) or ``_NEEDS_PLANNED`` (check
    times (a)); a run after a stop does all from the start, with what the stop asked for.
    """
    earlier = knots[0]
    points = (knots[0].copy(), knots[1].copy(), knots[2].copy(), knots[3].copy())
    # No cells: a point is placed on a sample only at its own time (within ``same``).
    context, no_cells = (source, evaluated), np.empty(0)
    split, split_steps = segments, steps
    for halving in range(halvings + 1):
        wanted = _spaced(points[0], _split_times(points[0], split_steps, split, source[0],
                                                 gap), gap)
        status, added, need = _placed(wanted, no_cells, no_cells, same, context)
        if status != _FOUND:
            return status, points[0], points[1], points[2], points[3], 0.0, need
        points = _joined(points, added)
        made = _new_segments(points[0], earlier)
        status, deviations, need = _evaluated_errors(points, made, made + 1, table, planned,
                                                     geometry, fractions, np.inf)
        if status != _FOUND:
            return status, points[0], points[1], points[2], points[3], 0.0, need
        failed = made[deviations > accept]
        if failed.size == 0:
            largest = 0.0
            for deviation in deviations:
                largest = max(largest, deviation)
            return _FOUND, points[0], points[1], points[2], points[3], largest, _no_need()
        # The failed segments are halved: at their middles, no step.
        split, split_steps = failed, np.empty(0)
    return _FOUND, points[0], points[1], points[2], points[3], np.inf, _no_need()


@kernel
def _split_times(times, steps, segments, sample_times, gap):
    """
    Return where points split ``segments`` (S,) between ``times``: at their steps, or middles.

    The ``steps`` (sorted) inside a segment, not within ``gap`` of its ends (a step closer is
    at that point already); a segment without one at its middle, moved to the
    sample nearest to it if that lies in the middle half of the segment. The steps in order,
    then the middles.
    """
    last = times.size - 2
    chosen = np.zeros(last + 1, np.bool_)
    chosen[segments] = True
    stepped = np.zeros(last + 1, np.bool_)
    inside = np.zeros(steps.size, np.bool_)
    for index in range(steps.size):
        step = steps[index]
        # The steps lie after the first point (t = 0), none at or after the last.
        segment = min(np.searchsorted(times, step, side='right') - 1, last)
        if (segment >= 0 and chosen[segment] and step > times[segment] + gap
                and step < times[segment + 1] - gap):
            inside[index] = True
            stepped[segment] = True
    halved = segments[~stepped[segments]]
    middles = 0.5 * (times[halved] + times[halved + 1])
    nearest = np.empty(halved.size, np.int64)
    usable = np.empty(halved.size, np.bool_)
    _nearest_samples(sample_times, middles, times[halved], times[halved + 1], 0.0, nearest,
                     usable)
    for index in range(halved.size):
        if usable[index]:
            middles[index] = sample_times[nearest[index]]
    return np.concatenate((steps[inside], middles))


@kernel
def _spaced(times, candidates, gap):
    """
    Return the ``candidates`` at least ``gap`` from ``times`` and from each other, sorted.

    In time order, each candidate also keeps the gap to the one accepted before it; none of
    ``times`` (the points there already).
    """
    candidates = np.sort(candidates)
    kept = np.empty(candidates.size)
    count, last = 0, -np.inf
    for index in range(candidates.size):
        candidate = candidates[index]
        if index > 0 and candidate == candidates[index - 1]:
            continue
        position = np.searchsorted(times, candidate)
        before = times[max(position - 1, 0)]
        after = times[min(position, times.size - 1)]
        if (abs(candidate - before) >= gap and abs(after - candidate) >= gap
                and candidate - last >= gap):
            kept[count] = candidate
            count, last = count + 1, candidate
    return kept[:count].copy()


@kernel
def _joined(points, added):
    """Return ``points`` (times, q, q_dot, q_ddot) and ``added`` in one, sorted by time."""
    times = np.concatenate((points[0], added[0]))
    order = np.argsort(times, kind='mergesort')
    return (times[order], np.concatenate((points[1], added[1]))[order],
            np.concatenate((points[2], added[2]))[order],
            np.concatenate((points[3], added[3]))[order])


@kernel
def _new_segments(times, earlier):
    """Return the segments between ``times`` with an end not in ``earlier`` (both sorted)."""
    last = earlier.size - 1
    old = np.empty(times.size, np.bool_)
    for point in range(times.size):
        old[point] = earlier[min(np.searchsorted(earlier, times[point]), last)] == times[point]
    return np.flatnonzero(~(old[:-1] & old[1:]))


def _planned_table(samples, accept):
    """
    Return the planned table the segment checks read for errors up to ``accept`` [m].

    :meth:`MotionSamples.planned_table` (C-contiguous and writeable: the one array type the
    kernels are compiled for), or ``_NO_TABLE`` below its resolution, where the motion
    itself is evaluated at every check point.
    """
    if accept < _PLANNED_TABLE_MIN_TOLERANCE:
        return _NO_TABLE
    return tuple(np.require(values, float, ('C', 'W')) for values in samples.planned_table())


@kernel
def _deviations_of(knots, segments, table, planned, geometry, fractions):
    """Return :func:`_segment_errors` of ``segments`` (S,) of ``knots``, none stopping."""
    # Evaluated directly: no search reruns from here, so no journal keeps them.
    return _evaluated_errors(knots, segments, segments + 1, table, planned, geometry,
                             fractions, np.inf)


# Outcomes of _search_knots: knots found; stopped for the motion's joint states at knot times
# no sample gives, or for its planned positions at check times (below the table's
# resolution); no knots at least the shortest interval apart meet the tolerance; an
# estimate of the knot count from the errors is not finite.
_FOUND, _NEEDS_STATES, _NEEDS_PLANNED, _TOO_FINE, _NOT_FINITE = range(5)
# No planned table: the check points' planned positions are evaluated (_Evaluated.planned).
_NO_TABLE = (np.empty(0), np.empty((3, 0)), np.empty((3, 0)))
# Where a run of _search_knots starts (a checkpoint's phase): at the initial knots, at a round
# of halving rejected segments (_refine), or at a trial of the re-placement (_replace).
_FROM_START, _REFINING, _REPLACING = range(3)
# The checkpoint of a search that starts at the initial knots (see _search_knots).
_START = (_FROM_START, 0, 0, 0, (np.empty(0), np.empty((0, 3)), np.empty((0, 3)),
                                 np.empty((0, 3))), np.empty(0), np.empty(0), np.empty(0))


class _Evaluated:
    """What the motion gave where the compiled search stopped for it, kept for its reruns."""

    def __init__(self):
        # Knots at times (E,) (sorted) with cos q, sin q, q_dot, q_ddot (E, 3).
        self.states = (np.empty(0), np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)),
                       np.empty((0, 3)))
        # Check times (P,) (sorted) and the planned positions there (P, 3).
        self.planned = (np.empty(0), np.empty((0, 3)))

    def add_states(self, times, states):
        """Keep the :func:`_motion_states` ``states`` of knots at ``times``."""
        self.states = _merged_rows(self.states, (times, *states))

    def add_planned(self, times, positions):
        """Keep the planned ``positions`` (N, 3) at check ``times`` (N,)."""
        self.planned = _merged_rows(self.planned, (times, positions))

    def supplied(self, status, samples, wanted):
        """
        Keep what a kernel that stopped with ``status`` needs; return whether it stopped.

        ``_NEEDS_STATES``: the states of knots wanted at ``wanted`` that no sample serves
        (:func:`_motion_states`); ``_NEEDS_PLANNED``: the planned positions at check times
        ``wanted``.
        """
        if status == _NEEDS_STATES:
            self.add_states(wanted, _motion_states(samples, wanted))
        elif status == _NEEDS_PLANNED:
            self.add_planned(wanted, _checked_state_at(samples.motion, wanted)[0])
        else:
            return False
        return True


def _motion_states(samples, times):
    """
    Return (cos q, sin q, q_dot, q_ddot) of the motion at ``times`` (K,), as samples have.

    The states of knots no sample serves (:meth:`MotionSamples.states` evaluates the motion at
    their times), their angles left to the kernel that places them, as a sample's.
    """
    return _joint_motion_at(times, *_checked_state_at(samples.motion, times)[:3],
                            samples.geometry, joint_trig_motion)


def _merged_rows(kept, added):
    """Return the arrays of ``kept`` with the rows of ``added``, sorted by the first."""
    order = np.argsort(np.concatenate((kept[0], added[0])), kind='stable')
    return tuple(np.ascontiguousarray(np.concatenate((old, np.asarray(new, dtype=float)))[order])
                 for old, new in zip(kept, added))


@kernel
def _search_knots(initial, source, evaluated, table, planned, geometry, fractions, accept,
                  shortest, journal, checkpoint):
    """
    Run the knot search of :func:`minimal_knots` from knots wanted at ``initial`` (K,).

    ``source`` = (times, cos q, sin q, q_dot, q_ddot) of the motion's samples, ``evaluated``
    the states of knots wanted where no sample is (:class:`_Evaluated`), ``table`` the planned
    table (:meth:`MotionSamples.planned_table`), or empty when the planned positions at the
    check points are those of ``planned`` (times, positions), ``geometry`` the first five of
    :func:`~ellipath_ros.core.kinematics._kernel_geometry`. Returns (status, times, q,
    q_dot, q_ddot, largest error, checkpoint, a, b, c, journal), with, for
    ``_NEEDS_STATES``, the times wanted and their cells (a, b, c) to evaluate; for
    ``_NEEDS_PLANNED``, the check times (a); for ``_TOO_FINE``, the time (a[0]) and error
    (b[0]) of the segment that cannot be split; for ``_NOT_FINITE``, the estimate that is
    not finite as the error.

    A run after a stop goes on from the ``checkpoint`` and ``journal`` the stopped one
    returned (``_START`` and an empty journal at first). The checkpoint (phase, trial,
    target, pruned, knots, errors, times, weights) is the state of the search at the start
    of the step that stopped for states: a round of :func:`_refine` or a trial of
    :func:`_replace`, which evaluate nothing before their placement stops; a run from it
    does what a run from the initial knots would do from there on (what the steps before
    used has not changed). A stop for planned positions keeps the checkpoint, and the
    journal holds the segment errors of every evaluation since it, in order: the next run
    repeats the stopped one up to the stop, and takes those errors from the journal instead
    of evaluating them again.
    """
    record = (journal, np.zeros(1, np.int64), [np.empty(0)])
    context = (source, evaluated, table, planned, geometry, fractions, record)
    phase, trial_number, target, pruned, knots, errors, times, weights = checkpoint
    status, need, error = _FOUND, _no_need(), 0.0
    if phase == _FROM_START:
        low, high = _cells(initial)
        status, knots, need = _placed(initial, low, high, 0.0, context)
        if status == _FOUND:
            # A rejected segment is halved (_refine): its error is not needed whole.
            index = np.arange(knots[0].size)
            status, errors, need = _segment_errors(knots, index[:-1], index[1:], context,
                                                   accept)
        phase = _REFINING
    moved = False
    if status == _FOUND and phase == _REFINING:
        status, knots, errors, need = _refine(knots, errors, context, accept, shortest)
        if status == _NEEDS_STATES:
            checkpoint, moved = (_REFINING, 0, 0, 0, knots, errors, times, weights), True
        # The re-placement from its start.
        trial_number = -1
    if status == _FOUND:
        status, knots, errors, need, error, state = _replace(
            knots, errors, context, accept, shortest,
            (trial_number, target, pruned, times, weights))
        if status == _NEEDS_STATES:
            checkpoint = (_REPLACING, state[0], state[1], state[2], knots, errors, state[3],
                          state[4])
            moved = True
    if status == _FOUND:
        error = errors.max()
    outcome = (status, knots[0], knots[1], knots[2], knots[3], error, checkpoint, need[0],
               need[1], need[2])
    if moved:
        # From a new checkpoint, the next run evaluates all it needs: no journal.
        return outcome + (np.empty(0),)
    batches = record[2]
    written = journal.size
    for batch in batches:
        written += batch.size
    journal_out = np.empty(written)
    journal_out[:journal.size] = journal
    written = journal.size
    for batch in batches:
        journal_out[written:written + batch.size] = batch
        written += batch.size
    return outcome + (journal_out,)


@kernel
def _cells(times):
    """Return the bounds (K,), (K,) within which knots wanted at ``times`` (K,) may move."""
    count = times.size
    low, high = np.empty(count), np.empty(count)
    low[0], high[-1] = -np.inf, np.inf
    for knot in range(count - 1):
        middle = 0.5 * (times[knot] + times[knot + 1])
        high[knot], low[knot + 1] = middle, middle
    return low, high


@kernel
def _no_need():
    """Return the empty (a, b, c) of an outcome that needs nothing evaluated."""
    return np.empty(0), np.empty(0), np.empty(0)


@kernel
def _placed(wanted, low, high, same, context):
    """
    Return (status, knots, need): knots wanted at ``wanted`` (K,), each within its cell.

    The rule of :meth:`MotionSamples.states`: the sample nearest to the wanted time if it
    lies in the middle half of the cell [``low``, ``high``] (without cells, size 0: within
    ``same`` of the wanted time), else the motion's state at the wanted time, taken from the
    evaluated ones. Knots (times, q, q_dot, q_ddot); status ``_NEEDS_STATES`` with the wanted
    times and cells evaluated nowhere yet. ``context`` starts with the ``source`` and
    ``evaluated`` of :func:`_search_knots`.
    """
    sample_times, cos_q, sin_q, qdot, qddot = context[0]
    evaluated_times, evaluated_cos_q, evaluated_sin_q, evaluated_qdot, evaluated_qddot = context[1]
    count = wanted.size
    nearest = np.empty(count, np.int64)
    usable = np.empty(count, np.bool_)
    _nearest_samples(sample_times, wanted, low, high, same, nearest, usable)
    times = np.empty(count)
    positions, velocities, accelerations = (np.empty((count, 3)), np.empty((count, 3)),
                                            np.empty((count, 3)))
    missing = np.zeros(count, np.bool_)
    found, searched = 0, np.inf
    # Element by element: a row view (qdot[row]) counts its array's references up and down.
    # A knot's q is the atan2 of its cos q and sin q (a sample's, or an evaluated one's), as
    # :func:`joint_angles` computes it.
    for knot in range(count):
        if usable[knot]:
            row = nearest[knot]
            times[knot] = sample_times[row]
            for axis in range(3):
                positions[knot, axis] = math.atan2(sin_q[row, axis], cos_q[row, axis])
                velocities[knot, axis] = qdot[row, axis]
                accelerations[knot, axis] = qddot[row, axis]
            continue
        # Wanted in order (as a rule): each search continues from the one before.
        row = _sorted_position(evaluated_times, wanted[knot],
                               found if wanted[knot] >= searched else 0)
        found, searched = row, wanted[knot]
        if row < evaluated_times.size and evaluated_times[row] == wanted[knot]:
            times[knot] = evaluated_times[row]
            for axis in range(3):
                positions[knot, axis] = math.atan2(evaluated_sin_q[row, axis],
                                                   evaluated_cos_q[row, axis])
                velocities[knot, axis] = evaluated_qdot[row, axis]
                accelerations[knot, axis] = evaluated_qddot[row, axis]
        else:
            missing[knot] = True
    knots = (times, positions, velocities, accelerations)
    if missing.any():
        cells = (low[missing], high[missing]) if low.size else (low, high)
        return _NEEDS_STATES, knots, (wanted[missing], cells[0], cells[1])
    return _FOUND, knots, _no_need()


@kernel
def _segment_errors(knots, start, end, context, limit, all_or_none=False):
    """
    Return (status, errors, need): the largest TCP deviation on each segment start -> end.

    Of JTC's quintic from knot ``start[s]`` to ``end[s]`` (arrays (S,)) through FK, from
    the planned positions, on the check grid (``fractions`` of the segment's length): those
    interpolated from the planned table, or the evaluated ones (status ``_NEEDS_PLANNED``
    with the check times not yet evaluated). A pose that cannot be assembled counts as inf.
    A segment's evaluation stops at the first error above ``limit`` (then its error is one
    above ``limit``, not the largest); with ``all_or_none`` the batch's does (see
    :func:`_evaluated_errors`). A run after a stop takes the errors of the stopped run from
    its journal (see :func:`_search_knots`), and adds the ones it evaluates.
    """
    journal, cursor, batches = context[6]
    if cursor[0] + start.size <= journal.size:
        cursor[0] += start.size
        return _FOUND, journal[cursor[0] - start.size:cursor[0]].copy(), _no_need()
    # Past the journal's end: no later batch is taken from it.
    cursor[0] = journal.size
    status, errors, need = _evaluated_errors(knots, start, end, context[2], context[3],
                                             context[4], context[5], limit, all_or_none)
    if status == _FOUND:
        batches.append(errors)
    return status, errors, need


@kernel
def _evaluated_errors(knots, start, end, table, planned, geometry, fractions, limit,
                      all_or_none=False):
    """
    :func:`_segment_errors` evaluated (the ``context``'s parts given), no journal.

    Below an infinite ``limit``, a segment's middle check point is taken first (the error of
    a segment too long peaks near its middle, so a rejected one stops there as a rule), then
    the others in order: the largest error is the same in any order. With ``all_or_none``,
    the batch stops at its first segment above ``limit``, and that one's error and all the
    later ones are inf (for a caller that needs the errors only if every segment passes).
    """
    rx, ry, offset, upper, forearm_sq = geometry
    times, positions, velocities, accelerations = knots
    count = fractions.size
    from_table = table[0].size > 0
    if not from_table:
        missing = _missing_check_times(times, start, end, fractions, planned[0])
        if missing.size:
            return _NEEDS_PLANNED, np.empty(0), (missing, np.empty(0), np.empty(0))
    # Visit -1 is the middle check point, taken first below a finite limit.
    probe = count // 2 if limit < np.inf else -1
    first_visit = -1 if probe >= 0 else 0
    c = np.empty((6, 3))
    expected = np.empty((1, 3))
    errors = np.empty(start.size)
    # The table's arrays taken out of their tuple once, not at every check point.
    table_times, table_positions, table_velocities = table
    final = table_times.size - 2
    for segment in range(start.size):
        first, second = start[segment], end[segment]
        t0 = times[first]
        length = times[second] - t0
        _fill_quintic(length, positions, positions, velocities, velocities, accelerations,
                      accelerations, first, second, c)
        worst = -np.inf
        # The table interval of the first check point, then walked along the later ones:
        # the interval _hermite_row would search for each (for the probe, searched).
        walked = min(max(np.searchsorted(table_times, t0 + length * fractions[0],
                                         side='right') - 1, 0), final)
        for visit in range(first_visit, count):
            sample = probe if visit < 0 else visit
            x = length * fractions[sample]
            if visit < 0:
                step = min(max(np.searchsorted(table_times, t0 + x, side='right') - 1, 0),
                           final)
            else:
                while walked < final and table_times[walked + 1] <= t0 + x:
                    walked += 1
                if visit == probe:
                    continue
                step = walked
            if from_table:
                _hermite_in(table_times, table_positions, table_velocities, step, t0 + x,
                            expected, 0)
            else:
                expected[0] = planned[1][np.searchsorted(planned[0], t0 + x)]
            error = np.inf
            # Forward kinematics inlined, on plain floats: a compiled call taking arrays
            # counts their references up and down at every check point.
            q0, q1, q2 = _polynomial(c, 0, x, 0), _polynomial(c, 1, x, 0), _polynomial(c, 2, x, 0)
            status, reached_x, reached_y, reached_z = _forward_point(
                math.cos(q0), math.sin(q0), math.cos(q1), math.sin(q1), math.cos(q2),
                math.sin(q2), rx, ry, offset, upper, forearm_sq)
            if status == _ASSEMBLED:
                dx = reached_x - expected[0, 0]
                dy = reached_y - expected[0, 1]
                dz = reached_z - expected[0, 2]
                error = math.sqrt(dx * dx + dy * dy + dz * dz)
                if error != error:
                    error = np.inf
            if error > worst:
                worst = error
                if worst > limit:
                    break
        errors[segment] = worst
        if all_or_none and worst > limit:
            errors[segment:] = np.inf
            break
    return _FOUND, errors, _no_need()


@kernel
def _missing_check_times(times, start, end, fractions, evaluated):
    """Return the check times of the segments start -> end not in ``evaluated`` (sorted)."""
    count = fractions.size
    checks = np.empty(start.size * count)
    for segment in range(start.size):
        t0 = times[start[segment]]
        length = times[end[segment]] - t0
        for sample in range(count):
            checks[segment * count + sample] = t0 + length * fractions[sample]
    found = np.zeros(checks.size, np.bool_)
    for row in range(checks.size):
        index = np.searchsorted(evaluated, checks[row])
        found[row] = index < evaluated.size and evaluated[index] == checks[row]
    return checks[~found]


@kernel
def _refine(knots, errors, context, accept, shortest):
    """
    Halve rejected segments until every segment error is <= accept; (status, knots...).

    A rejected segment's error need only be above ``accept`` (it is halved): the halves are
    evaluated up to their first check point above it. The one too short to halve is
    evaluated whole for the outcome's error.
    """
    while True:
        rejected = errors > accept
        if not rejected.any():
            return _FOUND, knots, errors, _no_need()
        times = knots[0]
        worst = -1
        for segment in np.flatnonzero(rejected):
            if worst < 0 or times[segment + 1] - times[segment] < times[worst + 1] - times[
                    worst]:
                worst = segment
        if times[worst + 1] - times[worst] < 2.0 * shortest:
            status, whole, need = _segment_errors(knots, np.full(1, worst),
                                                  np.full(1, worst + 1), context, np.inf)
            if status != _FOUND:
                return status, knots, errors, need
            return (_TOO_FINE, knots, errors,
                    (np.full(1, times[worst]), whole, np.empty(0)))
        start = np.flatnonzero(rejected)
        status, middle, need = _placed(0.5 * (times[start] + times[start + 1]),
                                       times[start], times[start + 1], 0.0, context)
        if status != _FOUND:
            return status, knots, errors, need
        # Each middle goes after its segment's start; the two halves are new segments.
        count = times.size + start.size
        position = np.arange(times.size) + np.searchsorted(start, np.arange(times.size),
                                                           side='left')
        added = start + np.arange(1, start.size + 1)
        merged = (np.empty(count), np.empty((count, 3)), np.empty((count, 3)),
                  np.empty((count, 3)))
        merged_times, merged_q, merged_qdot, merged_qddot = merged
        for source_knots, rows in ((knots, position), (middle, added)):
            # Element by element, the arrays out of their tuples once: a tuple item or a row
            # view counts its array's references up and down.
            source_times, source_q, source_qdot, source_qddot = source_knots
            for knot in range(rows.size):
                row = rows[knot]
                merged_times[row] = source_times[knot]
                for axis in range(3):
                    merged_q[row, axis] = source_q[knot, axis]
                    merged_qdot[row, axis] = source_qdot[knot, axis]
                    merged_qddot[row, axis] = source_qddot[knot, axis]
        child = np.zeros(count - 1, np.bool_)
        child[added - 1] = True
        child[added] = True
        new_errors = np.empty(count - 1)
        new_errors[~child] = errors[~rejected]
        halves = np.flatnonzero(child)
        status, half_errors, need = _segment_errors(merged, halves, halves + 1, context,
                                                    accept)
        if status != _FOUND:
            return status, knots, errors, need
        new_errors[halves] = half_errors
        knots, errors = merged, new_errors


@kernel
def _prune(knots, errors, context, accept):
    """
    Drop interior knots while the segment replacing one and its neighbours is accepted.

    A round evaluates only the candidate segments that the knots it dropped made new: one
    whose three knots were neighbours in the round before is that round's candidate, its
    error (and the check points it stopped at) the same.
    """
    # The last round's candidates' errors, and which of its knots this round kept (none yet).
    last_errors, kept = np.empty(0), np.empty(0, np.int64)
    while knots[0].size > 2:
        count = knots[0].size
        candidates = np.arange(count - 2)
        # The segment from c to c + 2 drops knot c + 1; one above accept is not needed whole.
        merged_errors = np.empty(count - 2)
        known = np.zeros(count - 2, np.bool_)
        if kept.size:
            known = kept[2:] - kept[:-2] == 2
            merged_errors[known] = last_errors[kept[:-2][known]]
        fresh = candidates[~known]
        status, fresh_errors, need = _segment_errors(knots, fresh, fresh + 2, context, accept)
        if status != _FOUND:
            return status, knots, errors, need
        merged_errors[~known] = fresh_errors
        acceptable = np.flatnonzero(merged_errors <= accept)
        if acceptable.size == 0:
            break
        removed = np.zeros(count, np.bool_)
        for candidate in acceptable[np.argsort(merged_errors[acceptable], kind='mergesort')]:
            if not (removed[candidate] or removed[candidate + 2]):
                removed[candidate + 1] = True
        kept = np.flatnonzero(~removed)
        left = kept[:-1]
        errors = np.where(kept[1:] - left == 1, errors[np.minimum(left, count - 2)],
                          merged_errors[np.minimum(left, count - 3)])
        knots = (knots[0][kept], knots[1][kept], knots[2][kept], knots[3][kept])
        last_errors = merged_errors
    return _FOUND, knots, errors, _no_need()


@kernel
def _replace(knots, errors, context, accept, shortest, resumed):
    """
    Re-place refined knots by their error density, then prune (steps 2 and 3).

    Dyadic halving leaves knots on a coarse lattice: trial sets with fewer segments are
    spread over the measured error density (:func:`_equidistributed`), and a set is kept
    only if every segment passes. ``resumed`` = (trial, target, pruned, times, weights): the
    state at the start of the trial to go on from (trial -1: from the start), with the
    :func:`_error_weights` of the last measured set (knots at ``times``). Returns
    (status, knots, errors, need, estimate, the state at the start of the last trial).
    """
    first_trial, target, pruned_before, times, weights = resumed
    pruned = pruned_before != 0
    if first_trial < 0:
        # Weighed once per measured set, for its estimate and its re-placement.
        first_trial, times, weights = 0, knots[0], _error_weights(errors)
        estimate = _segment_count(weights, accept)
        if estimate < 0:
            return (_NOT_FINITE, knots, errors, _no_need(), _weight_sum(weights),
                    (0, target, 0, times, weights))
        target = min(estimate, times.size - 2)
        pruned = False
    state = (first_trial, target, 1 if pruned else 0, times, weights)
    for trial_number in range(first_trial, _REPLACEMENTS):
        if target < 1:
            break
        state = (trial_number, target, 1 if pruned else 0, times, weights)
        wanted = _equidistributed(times, weights, target)
        low, high = _cells(wanted)
        status, trial, need = _placed(wanted, low, high, 0.0, context)
        if status != _FOUND:
            return status, knots, errors, need, 0.0, state
        trial_times = trial[0]
        if (trial_times[1:] - trial_times[:-1]).min() < shortest:
            break
        index = np.arange(trial_times.size)
        # A set that fails ends the trials when it is the last or has one segment fewer than
        # the knots (the next would have as many, below): then only a set that passes needs
        # its errors, and the evaluation stops at the first segment above accept.
        decisive = trial_number == _REPLACEMENTS - 1 or target + 1 >= knots[0].size - 1
        status, trial_errors, need = _segment_errors(
            trial, index[:-1], index[1:], context, accept if decisive else np.inf, decisive)
        if status != _FOUND:
            return status, knots, errors, need, 0.0, state
        if not np.isfinite(trial_errors).all():
            # JTC's quintic between two trial knots passes a pose the arms cannot assemble
            # (or a decisive set failed, its later errors inf): the set is rejected, and the
            # next has one segment more, spread by the last finite measurement (which the
            # error density needs).
            target += 1
            if target >= knots[0].size - 1:
                break
            continue
        times, weights = trial_times, _error_weights(trial_errors)
        estimate = _segment_count(weights, accept)
        if estimate < 0:
            return _NOT_FINITE, knots, errors, _no_need(), _weight_sum(weights), state
        if (trial_errors <= accept).all():
            status, knots, errors, need = _prune(trial, trial_errors, context, accept)
            if status != _FOUND:
                return status, knots, errors, need, 0.0, state
            pruned = True
            target = min(estimate, knots[0].size - 2)
        else:
            target = max(estimate, target + 1)
            if target >= knots[0].size - 1:
                break
    if not pruned:
        status, knots, errors, need = _prune(knots, errors, context, accept)
        return status, knots, errors, need, 0.0, state
    return _FOUND, knots, errors, _no_need(), 0.0, state


@kernel
def _error_weights(errors):
    """Return ``errors ** (1/6)`` (each at least 1e-300 ** (1/6)): see _equidistributed."""
    weights = np.empty(errors.size)
    for segment in range(errors.size):
        weights[segment] = max(errors[segment], 1e-300) ** (1.0 / 6.0)
    return weights


@kernel
def _weight_sum(weights):
    """
    Return the sum of ``weights`` (:func:`_error_weights`), as ``numpy.sum`` adds up to 128.

    NumPy's pairwise summation: a plain loop below 8 values, else eight interleaved partial
    sums (to 128 values; NumPy halves longer arrays, here blocks of 128 are added in turn),
    so that the estimates equal NumPy's.
    """
    total = 0.0
    for first in range(0, weights.size, 128):
        block = weights[first:first + 128]
        if block.size < 8:
            part = 0.0
            for value in block:
                part += value
        else:
            partial = block[:8].copy()
            row = 8
            while row < block.size - block.size % 8:
                partial += block[row:row + 8]
                row += 8
            part = (((partial[0] + partial[1]) + (partial[2] + partial[3]))
                    + ((partial[4] + partial[5]) + (partial[6] + partial[7])))
            for value in block[row:]:
                part += value
        total += part
    return total


@kernel
def _segment_count(weights, accept):
    """
    Estimate how many segments keep every error at ``accept``; -1 if the errors say nothing.

    From the measured segments' ``weights`` (:func:`_error_weights`): see
    :func:`_equidistributed`; -1 when their sum is not finite.
    """
    total = _weight_sum(weights)
    if not math.isfinite(total):
        return -1
    return max(1, math.ceil(total / accept ** (1.0 / 6.0)))


@kernel
def _equidistributed(times, weights, count):
    """
    Return ``count + 1`` knot times that spread an estimated error density evenly.

    On a smooth stretch the quintic's error grows like ``C h^6`` with the segment length h, so
    ``(error / h^6)^(1/6)``, constant on each measured segment, is a local density whose
    integral over a segment is ``error^(1/6)``: the segment's weight (:func:`_error_weights`
    of the errors measured on the segments between ``times``). Knots at equal steps of its
    integral balance the segment errors. The arithmetic of ``numpy.cumsum``, ``linspace`` and
    ``interp``.
    """
    cumulative = np.empty(times.size)
    cumulative[0] = 0.0
    for segment in range(weights.size):
        cumulative[segment + 1] = cumulative[segment] + weights[segment]
    step = cumulative[-1] / count
    new_times = np.empty(count + 1)
    new_times[0], new_times[-1] = times[0], times[-1]
    for knot in range(1, count):
        level = knot * step
        # The segment whose measured weight holds this level: last start at or below it.
        segment = min(np.searchsorted(cumulative, level, side='right') - 1, weights.size - 1)
        slope = (times[segment + 1] - times[segment]) / (
            cumulative[segment + 1] - cumulative[segment])
        new_times[knot] = slope * (level - cumulative[segment]) + times[segment]
    return new_times
