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
Conveyor tracking: pick from a moving belt (and place onto one).

Design. The paper's path (vertical lift, elliptical arc, vertical descent) is
planned in a frame that moves with the belt, and the frame's own motion is
superposed: base position = relative position + frame displacement. Each leg's
frame moves with the velocity of the belt it leaves during the lift, changes
its velocity with a jerk-limited S-curve while the TCP is on the arc, and moves
with the velocity of the belt it reaches during the descent. So, relative to
the object, the descent and the lift are exactly vertical over their whole
clearance; during the pick dwell the TCP moves with the belt. The limits hold
in the base frame because the budget is split (conservative, by the triangle
inequality): the frame's change uses at most ``FRAME_LIMIT_SHARE`` of the
acceleration and jerk limits and the relative motion the rest; the relative
motion's speed limit is the TCP limit less the fastest belt.

A cycle is three or four pieces, each one motion planned and checked by the
planner's own machinery (knots, executed JTC limits, workspace along the whole
moving motion): the approach (an optional wait at the start, then the leg from
rest onto the moving object), the pick dwell (moving with the belt), the
transfer (onto the place, moving with the place belt), and, when the place belt
moves, the place dwell on it and an exit (a vertical lift off the tray, then the
frame brought to rest) so that the trajectory ends at rest as JTC requires.

Intercept. The pick time is unknown: the object moves while the robot
approaches it, and a leg's duration jumps where the paper's rule rounds the
ellipse's angle, so no fixed-point iteration on the target can be exact. Two
free quantities make it exact instead: the midpoint of the frame's velocity
change (anywhere in the arc with room for the S-curve) and a wait at the start.
For a relative target lam along the belt, they are chosen so that the TCP meets
the object exactly (see :func:`_intercept`); lam is feasible when they fit,
and the smallest feasible lam (the earliest pick, to ``INTERCEPT_RESOLUTION``)
is found by a secant on the feasibility margin, which rises about 1/speed per
metre of lam because the leg's durations change slowly with its target
(:class:`_EarliestSearch`): usually three leg timings, bracketing where the
duration jumps, in at most ``INTERCEPT_ITERATIONS`` timings, with a clear error
otherwise. The transfer to a place (still, or on a parallel tray belt) is met
the same way, through the midpoint of its frame change, aimed first with the
approach's durations (usually one timing). Each leg's JTC points are searched
once, for the chosen leg only. An object that leaves the tracking
window before the robot can be on it is rejected as ``missed``, naming by how
much time and distance.

Place belts at any angle. The transfer's frame moves with the pick belt v0
during the lift and with the place belt v1 during the descent: the paper's
path is planned in that frame (relative to the object while leaving it,
relative to the tray while reaching it), and its velocity change v0 -> v1 is
superposed on the arc. A leg's timing error dT (its duration differs from the
one its target was aimed with) moves the end by v1 dT. The change's midpoint
moves it along v0 - v1 only, which suffices when the belts are still or
parallel; at an angle (say 90 degrees) the rest lies across, in the plane of v0
and v1, and a second free quantity is needed. It is an extension e >= 0 of the
pick dwell: the relative motion starts e later while the TCP goes on moving
with the object, which moves the end along v0; with the midpoint that spans the
plane, so the place is met exactly (e = aimed duration - T). Why this one: the
place target is the user's (``place`` is where the tray is at the place
instant, which the robot chooses; a place time or a position along the place
belt left free would move the object off the slot it is aimed at by v1 dT, up
to centimetres where the duration jumps, and would need a tray latch the
interface does not have), a second velocity change would take acceleration and
jerk from the budget, and riding with the gripped object a little longer
costs only e of cycle time and keeps every other property of the pick. e is
made small by aiming the transfer's duration (see :func:`_transfer`): a median
of 0.3-0.5 ms over 100 random pairs of belts, at most 6 ms but for two short hops (43 and
125 ms). The place target's position along its belt is thus never free: it is ``place``.
"""

from dataclasses import dataclass, field, replace
import math

import numpy as np

from .errors import (
    DegenerateGeometryError, EllipathError, InvalidInputError, LimitError, MissedError,
    require_finite, require_point, require_range)
from .geometry import plan_path
from .joint_trajectory import check_joint_limits, on_whole_nanoseconds, validate_jtc
from .limits import CartesianLimits
from .motion import TimedMotion
from .planner import (
    _check_executed_workspace, _concatenate, _cycle_inputs, _excess_factor, _hold, _joint_points,
    _QUINTIC_CHECK_SAMPLES, _rest_point, _SAME_POINT, CyclePlan, executed_bounds,
    EXECUTED_KEYS, LegPlan, plan_cycle, PlannerConfig)
from .settings import default_of, validate
from .timing import time_motion

# Share of max_accel and max_jerk the frame's velocity change may use; the relative motion
# is planned with the rest, so that their sum stays within the limits.
FRAME_LIMIT_SHARE = 0.2
# The transfer's end is solved to this distance from the place [m] (1/1000 of the 0.1 mm a
# belt pick needs), in at most this many iterations (also the intercept's bound).
INTERCEPT_TOLERANCE = 1e-7
INTERCEPT_ITERATIONS = 40
# The earliest pick is found to this resolution along the belt [m] (0.3 ms at 0.3 m/s; the
# TCP meets the object exactly whatever it is); past a relative target with no path to it,
# the search steps this long [s] times the belt speed, doubled each time.
INTERCEPT_RESOLUTION = 1e-4
INTERCEPT_STEP = 0.01
# What a trial pick with no path to it (a relative target almost straight below the start)
# counts as in the search: infeasible by this much [s].
DEGENERATE_PENALTY = 0.05
# Where the arc is shorter than this many times the frame's shortest change, the relative
# motion is slowed down to that: the change then has room to move, which the solvers use.
RAMP_ROOM = 1.5
# Re-plans of a whole cycle with lowered relative limits when its executed motion breaks one.
BELT_SLOWDOWN_ATTEMPTS = 3
# Lowered limits: this much beyond the measured excess.
BELT_SLOWDOWN_MARGIN = 1.02
# Belt speeds below this are zero [m/s]: a static pick, planned by plan_cycle itself.
STILL_BELT = 1e-9
# A transfer whose relative target is too close below its lift-off for an ellipse is aimed
# this much further aside along the frame's change [m] (see _transfer).
TRANSFER_ASIDE = 0.01
# A wait at the start shorter than this is none [s] (see _intercept).
SHORTEST_WAIT = 1e-6
# On angled belts, the transfer is aimed again (at most this many more times) while the pick
# dwell's extension it needs is longer than this [s]: each aim from the last duration shrinks it.
EXTENSION_GOAL = 1e-3
EXTENSION_TIMINGS = 3
# Belts whose directions' sine is below this are parallel: the transfer then needs no
# extension of the pick dwell (see _transfer); the part of its timing error across the change
# it leaves, |v1| dT sine, is far below INTERCEPT_TOLERANCE, and re-aiming shrinks dT.
PARALLEL_SINE = 1e-6
# Largest belt speed accepted [m/s].
MAX_BELT_SPEED = 2.0
# Orders in which waiting belt objects are taken (see next_belt_pick).
PICK_ORDERS = ('latch', 'soonest')


def _require_velocity(name, value):
    velocity = require_point(name, value)
    speed = float(np.linalg.norm(velocity))
    if speed > MAX_BELT_SPEED:
        raise InvalidInputError(
            f'{name}: expected a speed of at most {MAX_BELT_SPEED:g} m/s, got {speed:.6g} m/s')
    return velocity


@dataclass(frozen=True)
class Conveyor:
    """
    The belts and the tracking window.

    Attributes
    ----------
    velocity : numpy.ndarray
        Pick belt velocity in the base frame [m/s], shape (3,); zero = static picks.
    place_velocity : numpy.ndarray
        Place belt (tray) velocity in the base frame [m/s], shape (3,), at any angle to
        ``velocity``; zero = static places.
    window_upstream, window_downstream : float
        Tracking window: positions along the pick belt's direction (the TCP position
        projected on the unit belt velocity, base frame) between which a pick may
        happen [m], upstream < downstream.

    """

    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    place_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    window_upstream: float = default_of('tracking_window_upstream')
    window_downstream: float = default_of('tracking_window_downstream')

    def __post_init__(self):
        object.__setattr__(self, 'velocity', _require_velocity('conveyor_velocity',
                                                               self.velocity))
        object.__setattr__(self, 'place_velocity', _require_velocity(
            'place_conveyor_velocity', self.place_velocity))
        upstream = validate('tracking_window_upstream', self.window_upstream)
        downstream = validate('tracking_window_downstream', self.window_downstream)
        object.__setattr__(self, 'window_upstream', upstream)
        object.__setattr__(self, 'window_downstream', downstream)
        if downstream <= upstream:
            raise InvalidInputError(
                f'tracking_window_downstream: expected a value > tracking_window_upstream = '
                f'{upstream:g} m, got {downstream:g} m')

    @property
    def moving(self):
        """Whether either belt moves (otherwise every pick is static)."""
        return bool(np.linalg.norm(self.velocity) > STILL_BELT
                    or np.linalg.norm(self.place_velocity) > STILL_BELT)

    @property
    def angled(self):
        """Whether both belts move, at an angle to each other (see _transfer)."""
        speeds = (float(np.linalg.norm(self.velocity)),
                  float(np.linalg.norm(self.place_velocity)))
        return bool(min(speeds) > STILL_BELT and np.linalg.norm(
            np.cross(self.velocity, self.place_velocity)) > PARALLEL_SINE * speeds[0] * speeds[1])

    def window_times(self, position, latch_time):
        """
        Return when the object latched at ``position`` at ``latch_time`` enters and leaves.

        Returns
        -------
        tuple of float
            (entry, exit) times on the latch clock [s]; (-inf, inf) on a still pick belt.

        """
        speed = float(np.linalg.norm(self.velocity))
        if speed <= STILL_BELT:
            return -math.inf, math.inf
        along = float(np.dot(position, self.velocity)) / speed
        return (latch_time + (self.window_upstream - along) / speed,
                latch_time + (self.window_downstream - along) / speed)


# -- the moving frame --------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class FrameRamp:
    """
    A frame whose velocity changes from ``v0`` to ``v1`` by a jerk-limited S-curve.

    The change starts at ``start`` and lasts ``duration``; its shape is the
    time-optimal one for ``accel`` and ``jerk`` (7 phases: jerk +j, 0, -j),
    stretched in time to ``duration`` (which lowers acceleration and jerk).
    The displacement is zero at t = 0.
    """

    v0: np.ndarray
    v1: np.ndarray
    start: float
    duration: float
    accel: float
    jerk: float

    def __post_init__(self):
        change = float(np.linalg.norm(self.v1 - self.v0))
        object.__setattr__(self, 'direction',
                           (self.v1 - self.v0) / change if change > 0.0 else np.zeros(3))
        ramp, hold = _ramp_phases(change, self.accel, self.jerk)
        shortest = 2.0 * ramp + hold
        if change > 0.0 and self.duration < shortest * (1.0 - 1e-9):
            raise InvalidInputError(
                f'frame ramp duration: expected at least {shortest:.6g} s, '
                f'got {self.duration:.6g} s')
        stretch = self.duration / shortest if shortest > 0.0 else 1.0
        jerk = self.jerk / stretch ** 2 if change > 0.0 else 0.0
        lengths = np.array([ramp, hold, ramp]) * stretch
        bounds = self.start + np.concatenate(([0.0], np.cumsum(lengths)))
        # The phases' sum may round past the end: the frame is exactly at v1 from its end on
        # (a trajectory must end at rest to the last bit).
        bounds[-1] = self.start + self.duration
        jerks = np.array([jerk, 0.0, -jerk])
        # State (x, u, a) of the scalar change at each phase start, integrated exactly.
        states = [np.zeros(3)]
        for length, value in zip(lengths, jerks):
            x, u, a = states[-1]
            states.append(np.array([
                x + u * length + a * length ** 2 / 2 + value * length ** 3 / 6,
                u + a * length + value * length ** 2 / 2, a + value * length]))
        object.__setattr__(self, 'bounds', bounds)
        object.__setattr__(self, 'jerks', jerks)
        object.__setattr__(self, 'states', np.array(states))
        object.__setattr__(self, 'change', change)

    @property
    def end(self):
        """Time at which the frame has reached ``v1`` [s]."""
        return self.start + self.duration

    @property
    def peak_speed(self):
        """Largest frame speed [m/s] (the S-curve is monotonic between v0 and v1)."""
        return float(max(np.linalg.norm(self.v0), np.linalg.norm(self.v1)))

    def state(self, t):
        """Return displacement, velocity, acceleration and jerk at times ``t``, (N, 3) each."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tau = np.clip(t, self.bounds[0], self.bounds[-1])
        phase = np.clip(np.searchsorted(self.bounds, tau, side='right') - 1, 0, 2)
        dt = tau - self.bounds[phase]
        x0, u0, a0 = self.states[phase].T
        jerk = self.jerks[phase]
        x = x0 + u0 * dt + a0 * dt ** 2 / 2 + jerk * dt ** 3 / 6
        u = u0 + a0 * dt + jerk * dt ** 2 / 2
        a = a0 + jerk * dt
        inside = (t > self.bounds[0]) & (t < self.bounds[-1])
        # After the change the frame goes on at v1: the change's own displacement grows by
        # its full size per second.
        x = x + self.change * np.maximum(t - self.bounds[-1], 0.0)
        e = self.direction
        displacement = np.outer(t, self.v0) + np.outer(x, e)
        # Exactly v1 after the change (a trajectory must end at rest to the last bit).
        velocity = np.where((t >= self.bounds[-1])[:, np.newaxis], self.v1,
                            self.v0 + np.outer(u, e))
        acceleration = np.outer(np.where(inside, a, 0.0), e)
        jerk_vector = np.outer(np.where(inside, jerk, 0.0), e)
        return displacement, velocity, acceleration, jerk_vector

    def jerk_steps(self):
        """Return the times (K,) and sizes (K,) of the frame's jerk steps."""
        if self.change == 0.0:
            return np.zeros(0), np.zeros(0)
        size = abs(self.jerks[0])
        return self.bounds.copy(), np.array([size, size, size, size])


def _ramp_phases(change, accel, jerk):
    """Return (jerk phase, constant-acceleration phase) durations of the fastest S-curve."""
    if change <= 0.0:
        return 0.0, 0.0
    if change <= accel ** 2 / jerk:
        return math.sqrt(change / jerk), 0.0
    return accel / jerk, change / accel - accel / jerk


def ramp_time(change, limits):
    """Return the shortest jerk-limited velocity change of size ``change`` [m/s] [s]."""
    ramp, hold = _ramp_phases(change, FRAME_LIMIT_SHARE * limits.max_accel,
                              FRAME_LIMIT_SHARE * limits.max_jerk)
    return 2.0 * ramp + hold


# -- superposed motion -------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class SuperposedMotion:
    """
    A relative motion in a moving frame plus the frame's motion: what the base frame sees.

    Position = ``anchor`` + relative(t - delay) - relative(0) + frame displacement(t).
    Before ``delay`` and after its end the relative motion rests. It has the
    interface the planner's point machinery needs (``duration``, ``state_at``,
    ``jerk_steps``) and the one ``LegPlan.summary`` reads (``metrics``,
    ``profile``, ``n_nodes``).

    Attributes
    ----------
    relative : TimedMotion or None
        The motion relative to the frame (None: rest).
    frame : FrameRamp
        The frame's velocity.
    anchor : numpy.ndarray
        Base-frame position at t = 0 [m], (3,).
    duration : float
        [s].
    delay : float
        Start of the relative motion [s].

    """

    relative: TimedMotion | None
    frame: FrameRamp
    anchor: np.ndarray
    duration: float
    delay: float = 0.0

    def __post_init__(self):
        require_range('duration', self.duration, 0.0, math.inf, low_open=True, unit='s')

    @property
    def profile(self):
        """Return the relative motion's profile name."""
        return self.relative.profile if self.relative is not None else 'rest'

    @property
    def n_nodes(self):
        """Return the relative motion's node count (curvature profile), else None."""
        return self.relative.n_nodes if self.relative is not None else None

    def state_at(self, t):
        """Return base-frame position, velocity, acceleration and jerk at ``t``, (N, 3) each."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        displacement, velocity, acceleration, jerk = self.frame.state(t)
        position = self.anchor + displacement
        if self.relative is None:
            return position, velocity, acceleration, jerk
        local = t - self.delay
        moving = (local > 0.0) & (local < self.relative.duration)
        r, rv, ra, rj = self.relative.state_at(np.clip(local, 0.0, self.relative.duration))
        origin = self.relative.state_at(np.zeros(1))[0][0]
        mask = moving[:, np.newaxis]
        return (position + r - origin, velocity + np.where(mask, rv, 0.0),
                acceleration + np.where(mask, ra, 0.0), jerk + np.where(mask, rj, 0.0))

    def jerk_steps(self):
        """Return the times (K,) and sizes (K,) of the jerk steps, inside (0, duration)."""
        times, sizes = self.frame.jerk_steps()
        if self.relative is not None:
            relative_times, relative_sizes = self.relative.jerk_steps()
            times = np.concatenate((times, relative_times + self.delay))
            sizes = np.concatenate((sizes, relative_sizes))
        inside = (times > 0.0) & (times < self.duration)
        order = np.argsort(times[inside])
        return times[inside][order], sizes[inside][order]

    def metrics(self, sample_period=1e-4):
        """Return duration and the planned peaks (speed, acceleration, jerk) in the base frame."""
        count = max(int(math.ceil(self.duration / sample_period)) + 1, 3)
        _, velocity, acceleration, jerk = self.state_at(np.linspace(0.0, self.duration, count))
        segments = (self.relative.segment_durations.tolist() if self.relative is not None
                    else [0.0, 0.0, 0.0])
        return {'duration': float(self.duration), 'segment_durations': segments,
                'peak_speed': float(np.linalg.norm(velocity, axis=1).max()),
                'peak_accel': float(np.linalg.norm(acceleration, axis=1).max()),
                'peak_jerk': float(np.linalg.norm(jerk, axis=1).max()),
                'accel_jump_T1': float(getattr(self.relative, 'accel_jump_T1', 0.0)),
                'accel_jump_T2': float(getattr(self.relative, 'accel_jump_T2', 0.0))}


# -- legs --------------------------------------------------------------------------------------

def relative_limits(limits, conveyor):
    """
    Return the limits left to the relative motion once the frame has its share.

    Speed: the TCP limit less the fastest belt (|v_rel + v_frame| <= |v_rel| + |v_frame|);
    acceleration and jerk: (1 - ``FRAME_LIMIT_SHARE``) of theirs.
    """
    belt = max(float(np.linalg.norm(conveyor.velocity)),
               float(np.linalg.norm(conveyor.place_velocity)))
    if belt >= 0.5 * limits.max_speed:
        raise LimitError(
            f'conveyor speed: expected below half of max_speed ({0.5 * limits.max_speed:g} '
            f'm/s), got {belt:.6g} m/s')
    share = 1.0 - FRAME_LIMIT_SHARE
    return CartesianLimits(limits.max_speed - belt, share * limits.max_accel,
                           share * limits.max_jerk, limits.max_accel_jump)


@dataclass(frozen=True, eq=False)
class _Leg:
    """
    A relative motion and where in it the frame's velocity may change.

    The change (an S-curve at least ``shortest`` long) fits in the arc,
    [``arc_start``, ``arc_end``]; its midpoint ``m`` is free in [``lowest``,
    ``highest``]. The frame's displacement over the leg is v1 T + (v0 - v1) m
    (a symmetric S-curve), so that freedom lets the solvers meet a target
    exactly even where the duration T jumps with the target (the paper's
    rule rounds the ellipse's angle to whole degrees). A leg with no arc (one
    straight line) changes the frame first, then moves: ``delay``.
    """

    relative: TimedMotion
    shortest: float
    arc_start: float
    arc_end: float
    delay: float

    @property
    def duration(self):
        """Return the leg's duration [s]."""
        return self.delay + self.relative.duration

    @property
    def lowest(self):
        """Return the earliest midpoint of the frame's change [s]."""
        if self.delay > 0.0 or self.shortest == 0.0:
            return 0.5 * self.shortest
        return self.arc_start + 0.5 * self.shortest

    @property
    def highest(self):
        """Return the latest midpoint of the frame's change [s]."""
        if self.delay > 0.0 or self.shortest == 0.0:
            return 0.5 * self.shortest
        return self.arc_end - 0.5 * self.shortest

    def frame(self, v0, v1, midpoint, config):
        """Return the frame ramp v0 -> v1 centred on ``midpoint`` (within the freedom)."""
        midpoint = min(max(midpoint, self.lowest), self.highest)
        if self.delay > 0.0 or self.shortest == 0.0:
            start, length = 0.0, self.shortest
        else:
            length = 2.0 * min(midpoint - self.arc_start, self.arc_end - midpoint)
            start = midpoint - 0.5 * length
        return FrameRamp(v0, v1, start, length, FRAME_LIMIT_SHARE * config.limits.max_accel,
                         FRAME_LIMIT_SHARE * config.limits.max_jerk)


def _moving_leg(start, target, change, config, limits, clearances):
    """
    Plan the relative motion from ``start`` to ``target`` for a frame change of ``change``.

    Where the arc is shorter than ``RAMP_ROOM`` times the shortest change, the
    relative motion is slowed down uniformly until it is that long.
    """
    try:
        path = plan_path(start, target, clearances[0], clearances[1], config.arc, config.join,
                         config.join_tolerance)
    except DegenerateGeometryError:
        # The relative target depends on the belt's motion: one a few millimetres beside the
        # start is incidental, not the user's choice. A tall ellipse (apex_clearance) is
        # sound down to about 3 mm sideways; closer still, this raises too.
        path = plan_path(start, target, clearances[0], clearances[1],
                         replace(config.arc, kind='apex_clearance'), config.join,
                         config.join_tolerance)
    relative = time_motion(path, limits, profile=config.profile, r=config.curvature_r)
    shortest = ramp_time(change, config.limits)
    lift, arc, _ = relative.segment_durations
    if shortest == 0.0:
        return _Leg(relative, 0.0, lift, lift + arc, 0.0)
    if arc <= 0.0:
        return _Leg(relative, shortest, 0.0, shortest, shortest)
    if arc < RAMP_ROOM * shortest:
        relative = relative.scaled(RAMP_ROOM * shortest / arc)
        lift, arc, _ = relative.segment_durations
    return _Leg(relative, shortest, lift, lift + arc, 0.0)


@dataclass(frozen=True)
class Intercept:
    """
    Where and when a belt pick happens (times on the latch clock).

    Attributes
    ----------
    pick_time : float
        The TCP is on the object [s].
    pick_position : numpy.ndarray
        The object's (and TCP's) position then [m], (3,).
    window_position : float
        Position along the belt direction at the pick [m].
    wait : float
        Rest at the start before the approach (the object was upstream) [s].
    margin_time : float
        Time left before the object leaves the window [s] (inf on a still belt).
    margin_distance : float
        Distance left to the downstream limit at the pick [m] (inf on a still belt).

    """

    pick_time: float
    pick_position: np.ndarray
    window_position: float
    wait: float
    margin_time: float
    margin_distance: float


def _intercept(start, start_time, pick, latch_time, conveyor, config, limits):
    """
    Return the Intercept and the approach leg (a _Leg and its FrameRamp).

    The approach's relative target is R(lam) = the pick's across-belt part +
    lam * u (u the belt direction). For a given lam, the frame's change
    midpoint m and the wait w at the start are chosen so that the TCP meets
    the object exactly: pick position along the belt y = lam + V (T - m),
    reached at t_s + w + T; the object is there then if w = (lam - V m - p_s) / V,
    p_s its position along the belt at the start. m is made as large as the
    leg allows, w >= 0 and y >= the window's upstream limit; lam is feasible when
    that m is not below the leg's lowest. The earliest pick is at the smallest
    feasible lam (:class:`_EarliestSearch`).
    """
    velocity = conveyor.velocity
    speed = float(np.linalg.norm(velocity))
    clearances = (config.place_clearance, config.pick_clearance)
    if speed <= STILL_BELT:
        leg = _moving_leg(start, pick, 0.0, config, limits, clearances)
        frame = leg.frame(np.zeros(3), np.zeros(3), 0.0, config)
        return Intercept(start_time + leg.duration, pick.copy(), 0.0, 0.0, math.inf,
                         math.inf), leg, frame
    direction = velocity / speed
    entry, leave = conveyor.window_times(pick, latch_time)
    if leave < start_time:
        late = start_time - leave
        raise MissedError(
            f'pick: expected an object inside the tracking window at the cycle start, got one '
            f'that left it {late:.4g} s before ({late * speed:.4g} m past the downstream '
            'limit)')
    across = pick - np.dot(pick, direction) * direction
    along_at_start = float(np.dot(pick, direction)) + speed * (start_time - latch_time)
    upstream = conveyor.window_upstream

    def solve(lam):
        try:
            leg = _moving_leg(start, across + lam * direction, speed, config, limits,
                              clearances)
        except DegenerateGeometryError:
            # No path to a target straight below the start: not a pick there.
            return _Trial(lam, -DEGENERATE_PENALTY, None, None)
        midpoint = min(leg.highest, (lam - along_at_start) / speed,
                       (lam + speed * leg.duration - upstream) / speed)
        return _Trial(lam, midpoint - leg.lowest, leg, midpoint)

    # The earliest feasible pick, then whether it is inside the window: a leg's duration is
    # not monotonic in its target (a short arc is slowed down to fit the frame's change), so
    # an infeasible trial's best case says nothing about a later one.
    search = _EarliestSearch(speed)
    trial = solve(along_at_start)
    for _ in range(INTERCEPT_ITERATIONS):
        following = search.propose(trial)
        if following is None:
            break
        trial = solve(following)
    else:
        raise LimitError(f'intercept: expected the earliest pick to within '
                         f'{INTERCEPT_RESOLUTION:g} m in {INTERCEPT_ITERATIONS} leg timings, '
                         f'got {search.describe()}')
    lam, leg, midpoint = search.best.lam, search.best.leg, search.best.midpoint
    frame = leg.frame(np.zeros(3), velocity, midpoint, config)
    midpoint = frame.start + 0.5 * frame.duration
    wait = (lam - speed * midpoint - along_at_start) / speed
    if wait < SHORTEST_WAIT:
        # Rounding leaves waits of a few 1e-18 s where none is needed; a point that close to
        # the start is not a valid JTC point. The TCP then misses by speed * wait, < 1 um.
        wait = 0.0
    along = lam + speed * (leg.duration - midpoint)
    if along > conveyor.window_downstream:
        _raise_missed(along, conveyor, speed)
    pick_time = start_time + wait + leg.duration
    position = across + along * direction
    return Intercept(pick_time, position, along, wait,
                     (conveyor.window_downstream - along) / speed,
                     conveyor.window_downstream - along), leg, frame


@dataclass(frozen=True, eq=False)
class _Trial:
    """One relative target lam along the belt, timed: feasible when ``value`` >= 0 [s]."""

    lam: float
    value: float
    leg: _Leg | None
    midpoint: float | None


class _EarliestSearch:
    """
    The smallest lam with value(lam) >= 0, each value one full leg timing.

    value(lam) is, where it matters, the wait left at the start (or the time the
    object has been in the window) less the leg's shortest time to the middle of
    its frame change: it rises by about 1/speed per metre of lam, because the
    leg's durations change slowly with its target. So a secant on the value,
    starting from the slope 1/speed, lands in the accepted band [0,
    ``INTERCEPT_RESOLUTION`` / speed] in two or three timings. Where the leg's
    duration jumps with the target (the paper's rule rounds the ellipse's angle),
    the secant may step over the band: then it continues between the closest
    infeasible and feasible trials by false position, halving where two steps did
    not halve the bracket, until the bracket is ``INTERCEPT_RESOLUTION`` wide.
    """

    def __init__(self, speed):
        self.speed = speed
        self.low = self.best = None  # the largest infeasible and smallest feasible trials
        self.previous = None
        self.step = speed * INTERCEPT_STEP
        self.widths = []

    def propose(self, trial):
        """Record ``trial``; return the next lam to time, or None once ``best`` is the pick."""
        band = INTERCEPT_RESOLUTION / self.speed
        if trial.value >= 0.0:
            if self.best is None or trial.lam < self.best.lam:
                self.best = trial
            if trial.value <= band:
                return None
        elif self.low is None or trial.lam > self.low.lam:
            self.low = trial
        if self.low is not None and self.best is not None:
            return self._inside()
        if trial.leg is None:
            # No leg to learn from (a degenerate relative target): step on, doubling.
            lam = trial.lam + self.step
            self.step *= 2.0
            return lam
        slope = 1.0 / self.speed
        previous = self.previous
        if previous is not None and previous.leg is not None and previous.lam != trial.lam:
            secant = (trial.value - previous.value) / (trial.lam - previous.lam)
            # The value rises about 1/speed per metre; a far steeper or flatter secant comes
            # from a jump of the duration, not from the trend.
            slope = min(max(secant, 0.25 / self.speed), 4.0 / self.speed)
        self.previous = trial
        lam = trial.lam + (0.5 * band - trial.value) / slope
        if trial.value < 0.0:
            lam = max(lam, trial.lam + INTERCEPT_RESOLUTION)
        return lam

    def _inside(self):
        low, high = self.low, self.best
        width = high.lam - low.lam
        if width <= INTERCEPT_RESOLUTION:
            return None
        self.widths.append(width)
        if len(self.widths) >= 3 and width > 0.5 * self.widths[-3]:
            lam = 0.5 * (low.lam + high.lam)
        else:
            # The secant between the bracket's ends, aimed at the middle of the band.
            target = 0.5 * INTERCEPT_RESOLUTION / self.speed
            lam = low.lam + (target - low.value) * width / (high.value - low.value)
        return min(max(lam, low.lam + 0.01 * width), high.lam - 0.01 * width)

    def describe(self):
        """Return the state of the search, for an error message."""
        if self.best is None:
            return 'no feasible pick'
        return (f'a bracket of {self.best.lam - self.low.lam:.3g} m' if self.low is not None
                else 'no bracket')


def _raise_missed(along, conveyor, speed):
    """Raise MissedError for a pick that could happen ``along`` at the earliest."""
    past = along - conveyor.window_downstream
    raise MissedError(
        f'pick: expected the robot on the object inside the tracking window, got it '
        f'{past / speed:.4g} s late ({past:.4g} m past the downstream limit '
        f'{conveyor.window_downstream:g} m)')


def _transfer(lift_off, place, conveyor, config, limits, clearances, approach):
    """
    Return the transfer leg, its FrameRamp and the pick dwell's extension [s].

    The frame moves with the pick belt v0 until its change, centred on m, to
    the place belt v1; the relative motion (duration T) starts after an
    extension e of the pick dwell (the TCP goes on moving with the object). It
    ends on ``place`` when its relative target is place - v1 T - (v0 - v1) m
    - v0 e. The target is aimed with a duration A and a midpoint (the first
    time the ``approach`` leg's, mirrored: its descent has the clearance of the
    transfer's lift) and e = 0; the leg timed, its own T differs from A. On
    belts that are still or parallel the error v1 (A - T) lies along v0 - v1
    and m alone absorbs it (e = 0). On angled belts it lies in the plane of v0
    and v1, and m and e absorb it together, exactly. There the aim is A and the
    time s from the change's midpoint to the place (target place - v0 A +
    (v0 - v1) s), and then e = A - T, m = T - s: s is taken inside the last
    leg's freedom, near its descent (so that it fits short legs too), and A is
    searched for e in [0, ``EXTENSION_GOAL``] (every millisecond of e is one of
    cycle): once from the leg's own duration, then by a secant on e(A), at most
    ``EXTENSION_TIMINGS`` legs past the first feasible one, the shortest e kept.
    Where the relative motion is a short hop (the belts carry the object
    almost to the place), T jumps with A by tenths of a second; after
    ``EXTENSION_TIMINGS`` legs with none feasible, A is raised past every T
    seen, by a step that doubles: T grows far slower than A there, so this ends.
    """
    v0, v1 = conveyor.velocity, conveyor.place_velocity
    change = v0 - v1
    size = float(np.linalg.norm(change))
    angled = conveyor.angled
    tolerance = INTERCEPT_TOLERANCE
    if angled:
        # The free quantities' directions: the extension's and the change's midpoint's.
        basis = np.column_stack((v0, change))
        tolerance += SHORTEST_WAIT * float(np.linalg.norm(v0))
    _, arc, descent = approach.relative.segment_durations
    aimed, midpoint = approach.duration, descent + 0.5 * arc
    target = place - v1 * aimed - change * midpoint
    best, trials = None, []  # the shortest feasible extension; (A, T, e, feasible) timed
    residual = math.inf
    for _ in range(INTERCEPT_ITERATIONS):
        try:
            leg = _moving_leg(lift_off, target, size, config, limits, clearances)
        except DegenerateGeometryError:
            if size == 0.0:
                raise
            # A pick next to the place: the relative target is almost straight below the
            # lift-off. The frame's change, aimed earlier or later, moves it aside along the
            # change; away from the lift-off.
            away = 1.0 if float(np.dot(target - lift_off, change)) >= 0.0 else -1.0
            target = target + away * TRANSFER_ASIDE * change / size
            continue
        rest = place - v1 * leg.duration - target
        extension, needed = 0.0, 0.0
        if angled:
            extension, needed = np.linalg.lstsq(basis, rest, rcond=None)[0]
            if abs(extension) < SHORTEST_WAIT:
                # As for the intercept's wait: no point that close to the lift-off; the TCP
                # then misses by |v0| e < 2 um, within the tolerance.
                extension = 0.0
                needed = float(np.dot(rest, change)) / size ** 2
        elif size > 0.0:
            needed = float(np.dot(rest, change)) / size ** 2
        frame = leg.frame(v0, v1, needed, config)
        residual = float(np.linalg.norm(
            rest - v0 * extension - change * (frame.start + 0.5 * frame.duration)))
        feasible = extension >= 0.0 and residual <= tolerance
        if feasible:
            if best is None or extension < best[2]:
                best = leg, frame, float(extension)
            if extension <= EXTENSION_GOAL or sum(
                    trial[3] for trial in trials) == EXTENSION_TIMINGS:
                return best
        if not angled:
            # Aim the frame's change at the middle of its freedom: the next leg's duration
            # may differ a little from this one's, and the freedom absorbs that.
            aimed = leg.duration
            target = place - v1 * aimed - change * 0.5 * (leg.lowest + leg.highest)
            continue
        trials.append((aimed, leg.duration, float(extension), feasible))
        aimed = _next_aim(trials, best is not None)
        # s: the freedom's start seen from the place, plus up to half the shortest change.
        before_place = leg.duration - leg.highest + min(0.5 * (leg.highest - leg.lowest),
                                                        0.5 * leg.shortest)
        target = place - v0 * aimed + change * before_place
    if best is not None:
        return best
    raise LimitError(
        f'transfer: expected the place reached to {INTERCEPT_TOLERANCE:g} m within '
        f'{INTERCEPT_ITERATIONS} iterations, got a residual of {residual:.3g} m')


def _next_aim(trials, found):
    """
    Return the next aimed duration A for an extension e(A) = A - T(A) in the goal's middle.

    ``trials`` are the (A, T, e, feasible) timed so far; ``found``: whether one was feasible.
    """
    goal = 0.5 * EXTENSION_GOAL
    aimed, duration, extension, _ = trials[-1]
    if not found and len(trials) >= EXTENSION_TIMINGS:
        # A short hop whose duration jumps with its aim: past every duration seen.
        step = goal * 2.0 ** (len(trials) - EXTENSION_TIMINGS)
        return max(max(trial[0] for trial in trials), max(trial[1] for trial in trials)) + step
    if len(trials) == 1:
        return duration + goal
    previous, _, previous_extension, _ = trials[-2]
    slope = 1.0
    if aimed != previous:
        # e rises 1 - dT/dA per second of aim; far steeper or flatter comes from a jump of
        # the duration, not from the trend.
        slope = min(max((extension - previous_extension) / (aimed - previous), 0.25), 4.0)
    return aimed + (goal - extension) / slope


def _exit(place, conveyor, config, limits):
    """Return the exit from a moving place: a vertical lift, then the frame brought to rest."""
    tray = conveyor.place_velocity
    relative = None
    lift = 0.0
    if config.place_clearance > 0.0:
        top = place + np.array([0.0, 0.0, config.place_clearance])
        relative = time_motion(plan_path(place, top, 0.0, 0.0, config.arc, config.join,
                                         config.join_tolerance),
                               limits, profile=config.profile, r=config.curvature_r)
        lift = relative.duration
    shortest = ramp_time(float(np.linalg.norm(tray)), config.limits)
    frame = FrameRamp(tray, np.zeros(3), lift, shortest,
                      FRAME_LIMIT_SHARE * config.limits.max_accel,
                      FRAME_LIMIT_SHARE * config.limits.max_jerk)
    return relative, frame, lift + shortest


@dataclass(frozen=True, eq=False)
class BeltCyclePlan(CyclePlan):
    """
    A :class:`CyclePlan` on belts, with its intercept.

    Attributes
    ----------
    intercept : Intercept or None
        When and where the pick happens (None on a still pick belt).
    start_time : float
        Time of the trajectory's t = 0 on the latch clock [s].

    """

    intercept: Intercept | None = None
    start_time: float = 0.0


def plan_belt_cycle(start, pick, place, config=None, conveyor=None, *, pick_dwell=0.0,
                    place_dwell=0.0, latch_time=0.0, start_time=0.0):
    """
    Plan a cycle whose pick is on a moving belt (and place, optionally, onto one).

    Parameters
    ----------
    start : array_like
        TCP position at the cycle start, at rest [m], (3,).
    pick : array_like
        Object position at ``latch_time`` [m], (3,).
    place : array_like
        Place position [m], (3,); on a moving place belt, its position at the
        time the TCP reaches it.
    config : PlannerConfig, optional
        Defaults when omitted.
    conveyor : Conveyor, optional
        Still belts (the default) give exactly :func:`plan_cycle`'s plan.
    pick_dwell, place_dwell : float
        Dwells [s], in [0, 10]; on a belt the TCP moves with it.
    latch_time, start_time : float
        When the object was at ``pick`` and when the trajectory starts, on one clock [s].

    Returns
    -------
    BeltCyclePlan

    Raises
    ------
    MissedError
        The object leaves the tracking window before the robot can reach it.
    EllipathError
        As :func:`plan_cycle`.

    """
    config = config or PlannerConfig()
    conveyor = conveyor or Conveyor()
    start, pick, place, pick_dwell, place_dwell = _cycle_inputs(
        start, pick, place, pick_dwell, place_dwell)
    latch_time = require_finite('latch_time', latch_time)
    start_time = require_finite('start_time', start_time)
    if not conveyor.moving:
        static = plan_cycle(start, pick, place, config, pick_dwell, place_dwell)
        return BeltCyclePlan(static.legs, static.joint_trajectory, static.metrics,
                             static.end_position, None, start_time)
    config.workspace.check(start, name='start')
    if np.linalg.norm(pick - start) <= _SAME_POINT:
        raise InvalidInputError(
            'start: expected the robot away from a moving object, got it on the pick')
    limits = relative_limits(config.limits, conveyor)
    attempts = 0
    while True:
        try:
            return _plan_pieces(start, pick, place, config, conveyor, limits, pick_dwell,
                                place_dwell, latch_time, start_time)
        except _ExecutedExcess as excess:
            attempts += 1
            if attempts == BELT_SLOWDOWN_ATTEMPTS:
                raise LimitError(f'{excess} after {attempts} slow-downs') from None
            # Lower the relative motion's limits as a uniform slow-down by the excess would.
            factor = excess.factor * BELT_SLOWDOWN_MARGIN
            limits = CartesianLimits(limits.max_speed / factor, limits.max_accel / factor ** 2,
                                     limits.max_jerk / factor ** 3, limits.max_accel_jump)


class _ExecutedExcess(Exception):
    """The executed motion of a piece breaks a limit by ``factor`` (uniform time scale)."""

    def __init__(self, message, factor):
        super().__init__(message)
        self.factor = factor


def _piece(name, relative, frame, anchor, delay, duration, config, bounds):
    """Return (LegPlan-like numbers, trajectory) of one superposed piece, checked."""
    motion = SuperposedMotion(relative, frame, np.asarray(anchor, dtype=float), duration,
                              delay)
    trajectory, error, table = _joint_points(motion, config, bounds)
    peaks = table.max(axis=0)
    if np.any(peaks > bounds):
        broken = ', '.join(f'{key} {peak:.6g} (bound {bound:.6g})'
                           for key, peak, bound in zip(EXECUTED_KEYS, peaks, bounds)
                           if peak > bound)
        raise _ExecutedExcess(f'executed {name}: expected the limits, got {broken}',
                              max(_excess_factor(peaks / bounds), 1.0 + 1e-3))
    check_joint_limits(trajectory, config.geometry, config.joint_limits,
                       samples_per_segment=_QUINTIC_CHECK_SAMPLES)
    _check_executed_workspace(trajectory, config, name)
    executed = {key: float(value) for key, value in zip(EXECUTED_KEYS, peaks)}
    path = relative.path if relative is not None else None
    knot_positions = motion.state_at(trajectory.time_from_start)[0]
    leg = LegPlan(path, motion, trajectory, knot_positions, error, executed[
        'joint_peak_velocity'], executed['joint_peak_accel'], 1.0, executed)
    return leg, trajectory, motion


def _plan_pieces(start, pick, place, config, conveyor, limits, pick_dwell, place_dwell,
                 latch_time, start_time):
    bounds = executed_bounds(config)
    intercept, leg, frame = _intercept(start, start_time, pick, latch_time, conveyor, config,
                                       limits)
    approach, trajectory, approach_motion = _piece(
        'approach', leg.relative, frame, start, leg.delay, leg.duration, config, bounds)
    if intercept.wait > 0.0:
        trajectory = _concatenate(_hold(_rest_point(trajectory), intercept.wait), trajectory)
    belt = conveyor.velocity
    lift_off = intercept.pick_position
    if pick_dwell > 0.0:
        _, dwell_trajectory, _ = _piece('pick dwell', None, _constant(belt, config), lift_off,
                                        0.0, pick_dwell, config, bounds)
        trajectory = _concatenate(trajectory, dwell_trajectory)
        lift_off = lift_off + belt * pick_dwell
    leg, frame, extension = _transfer(lift_off, place, conveyor, config, limits,
                                      (config.pick_clearance, config.place_clearance), leg)
    # The extension of the pick dwell: the relative motion and the frame's change start later.
    transfer, transfer_trajectory, transfer_motion = _piece(
        'transfer', leg.relative, replace(frame, start=frame.start + extension), lift_off,
        leg.delay + extension, leg.duration + extension, config, bounds)
    trajectory = _concatenate(trajectory, transfer_trajectory)
    end = place
    tray = conveyor.place_velocity
    if np.linalg.norm(tray) > STILL_BELT:
        if place_dwell > 0.0:
            _, dwell_trajectory, _ = _piece('place dwell', None, _constant(tray, config), end,
                                            0.0, place_dwell, config, bounds)
            trajectory = _concatenate(trajectory, dwell_trajectory)
            end = end + tray * place_dwell
        relative, frame, duration = _exit(end, conveyor, config, limits)
        _, exit_trajectory, exit_motion = _piece('exit', relative, frame, end, 0.0, duration,
                                                 config, bounds)
        trajectory = _concatenate(trajectory, exit_trajectory)
        end = exit_motion.state_at(np.array([duration]))[0][0]
    else:
        trajectory = _hold(trajectory, place_dwell)
    trajectory = on_whole_nanoseconds(trajectory)
    validate_jtc(trajectory, config.joint_names)
    legs = (approach, transfer)
    metrics = {f'transfer.{key}': value for key, value in transfer.summary().items()
               if isinstance(value, (int, float, str))}
    metrics.update({f'approach.{key}': value for key, value in approach.summary().items()
                    if isinstance(value, (int, float, str))})
    metrics.update({
        'duration': float(trajectory.time_from_start[-1]),
        'n_points': int(trajectory.time_from_start.size),
        'executed.max_interpolation_error': max(leg.max_interpolation_error for leg in legs),
        # Relative times: diagnostics print 9 significant digits, too few for clock times.
        'belt.pick_after_latch': intercept.pick_time - latch_time,
        'belt.pick_after_start': intercept.wait + approach_motion.duration,
        'belt.place_after_start': (intercept.wait + approach_motion.duration + pick_dwell
                                   + transfer_motion.duration),
        'belt.window_position': intercept.window_position,
        'belt.wait': intercept.wait,
        'belt.pick_dwell_extension': extension,
        'belt.margin_time': intercept.margin_time,
        'belt.margin_distance': intercept.margin_distance,
    })
    return BeltCyclePlan(legs, trajectory, metrics, np.asarray(end, dtype=float), intercept,
                         start_time)


def next_belt_pick(start, start_time, candidates, place, config=None, conveyor=None, *,
                   pick_dwell=0.0, place_dwell=0.0, order='soonest'):
    """
    Choose and plan the next belt pick among the objects waiting; report the missed ones.

    Parameters
    ----------
    start : array_like
        TCP position at the cycle start, at rest [m], (3,).
    start_time : float
        When the cycle starts, on the latch clock [s].
    candidates : sequence of (int, float, array_like)
        The objects latched and not yet picked: (number, latch time [s], position at the
        latch [m]), in latch order.
    place, config, conveyor, pick_dwell, place_dwell
        As :func:`plan_belt_cycle`.
    order : str
        ``'latch'``: the first object in latch order that can still be caught (what a FIFO
        of pairs does; with one camera, the most downstream). ``'soonest'``: every waiting
        object is planned and the one whose cycle ends first is taken (the robot is free
        soonest for the next), unless the first catchable in latch order could not be
        caught after it; then that one.

    Returns
    -------
    tuple
        (number, BeltCyclePlan) of the pick, or (None, None) when none can be caught; and a
        dict {number: EllipathError} of the objects rejected on the way (missed from this
        start, they are missed from any later one: they are further downstream by then).

    """
    if order not in PICK_ORDERS:
        raise InvalidInputError(f'order: expected one of {PICK_ORDERS}, got {order!r}')
    options = {'pick_dwell': pick_dwell, 'place_dwell': place_dwell}
    rejected, plans = {}, {}
    for number, latch_time, position in candidates:
        try:
            plans[number] = plan_belt_cycle(start, position, place, config, conveyor,
                                            latch_time=latch_time, start_time=start_time,
                                            **options)
        except EllipathError as error:
            rejected[number] = error
            continue
        if order == 'latch':
            break
    if not plans:
        return (None, None), rejected
    first = next(iter(plans))  # the first in latch order that can be caught
    soonest = min(plans, key=lambda number: plans[number].joint_trajectory.duration)
    if soonest != first:
        # Only if the first can still be caught after it (to the same place): otherwise
        # taking the soonest would trade one pick for another.
        after = plans[soonest]
        latch_time, position = next((latch_time, position)
                                    for number, latch_time, position in candidates
                                    if number == first)
        try:
            plan_belt_cycle(after.end_position, position, place, config, conveyor,
                            latch_time=latch_time,
                            start_time=start_time + after.joint_trajectory.duration, **options)
        except EllipathError:
            soonest = first
    return (soonest, plans[soonest]), rejected


def _constant(velocity, config):
    """Return a frame moving at ``velocity`` throughout."""
    return FrameRamp(velocity, velocity, 0.0, 0.0, FRAME_LIMIT_SHARE * config.limits.max_accel,
                     FRAME_LIMIT_SHARE * config.limits.max_jerk)
