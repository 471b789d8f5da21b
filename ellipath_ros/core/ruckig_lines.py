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
Ruckig on one degree of freedom: time-optimal pieces along a straight or gently curved stretch.

Ruckig's own error text is kept where it refuses a state (see :func:`_ruckig_solution`).
"""

import math
import threading

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from .errors import LimitError
from .limits import (
    _ACCEL_MARGIN, _cap_values, _even_samples, _JERK_MARGIN, _LIMIT_SAMPLES, _SPEED_MARGIN)
from .motion import _PieceList, TimedMotion

# Each thread's Ruckig objects (see _solver).
_SOLVERS = threading.local()


def _ruckig_rows(start, target, speed, accel, jerk):
    """
    Return the time-optimal 1-DoF pieces from ``start`` to ``target`` (s, s', s''), or None.

    None when Ruckig finds nothing or the motion is not monotone (it would
    overshoot and come back: the distance is too short for the states);
    :func:`_ruckig_solution` says why.
    """
    return _ruckig_solution(start, target, speed, accel, jerk)[0]


def _ruckig_solution(start, target, speed, accel, jerk):
    """
    Return (rows, None) as :func:`_ruckig_rows` does, or (None, why) with Ruckig's own text.

    Each row is (duration, s, s', s'', s''') of one constant-jerk piece.
    """
    data, ruckig, trajectory = _solver()
    # Every input a solve reads is set anew: nothing of the previous solve carries over.
    data.current_position, data.current_velocity, data.current_acceleration = (
        [start[0]], [start[1]], [start[2]])
    data.target_position, data.target_velocity, data.target_acceleration = (
        [target[0]], [target[1]], [target[2]])
    data.max_velocity, data.max_acceleration, data.max_jerk = [speed], [accel], [jerk]
    try:
        result = ruckig.calculate(data, trajectory)
    except RuckigError as error:
        # Ruckig refuses states beyond its limits (e.g. a target acceleration above them).
        return None, f'Ruckig refused the states: {str(error).strip()}'
    if result != Result.Working:
        return None, f'Ruckig returned {result.name}'
    profile = trajectory.profiles[0][0]
    brake = profile.brake
    # Each attribute read converts the whole array to a list: read once, zipped per phase (the
    # brake's two, only if one of them lasts, then the profile's seven; zip stops at the
    # durations, the shortest).
    durations = brake.t
    rows = ([row for row in zip(durations, brake.p, brake.v, brake.a, brake.j) if row[0] > 0.0]
            if durations[0] > 0.0 or durations[1] > 0.0 else [])
    rows += [row for row in zip(profile.t, profile.p, profile.v, profile.a, profile.j)
             if row[0] > 0.0]
    for duration, _, v, a, j in rows:
        # Smallest speed on the piece: at its ends or where s'' = 0 inside it (of equals the
        # first, as min() keeps it).
        lowest = v
        end_speed = v + a * duration + 0.5 * j * duration ** 2
        if end_speed < lowest:
            lowest = end_speed
        if j != 0.0 and 0.0 < -a / j < duration:
            vertex_speed = v - 0.5 * a * a / j
            if vertex_speed < lowest:
                lowest = vertex_speed
        if lowest < -1e-9:
            return None, (f"Ruckig's motion runs backwards (speed down to {lowest:.3g} "
                          'm/s): the distance is too short for the end states')
    return rows, None


def _solver():
    """
    Return this thread's (InputParameter, Ruckig, Trajectory) of one degree of freedom.

    Made once per thread instead of per solve (a few microseconds, eight solves a request): a
    solve sets every input it reads and overwrites the trajectory, so none depends on the one
    before; one set per thread, as the node may plan in more than one.
    """
    try:
        return _SOLVERS.parts
    except AttributeError:
        _SOLVERS.parts = InputParameter(1), Ruckig(1), Trajectory(1)
        return _SOLVERS.parts


def _reach_speed(distance, accel, jerk):
    """Return the largest speed reachable from rest over ``distance`` ending at s'' = 0."""
    if distance <= 0.0:
        return 0.0
    # Without a constant-acceleration phase: distance = v sqrt(v / J).
    speed = (distance * math.sqrt(jerk)) ** (2.0 / 3.0)
    if speed <= accel * accel / jerk:
        return speed
    # With one: distance = v (v / A + A / J) / 2.
    ratio = accel / jerk
    return 0.5 * accel * (-ratio + math.sqrt(ratio * ratio + 8.0 * distance / accel))


def _line_rows(start, target, limits, speed_cap, s_from, s_to):
    """Return Ruckig pieces along a straight segment [s_from, s_to] (None if none fit)."""
    return _line_solution(start, target, limits, speed_cap, s_from, s_to)[0]


def _line_solution(start, target, limits, speed_cap, s_from, s_to):
    """Return (rows, None) as :func:`_line_rows` does, or (None, why) with Ruckig's text."""
    return _ruckig_solution(start, target, _line_speed(limits, speed_cap, s_from, s_to),
                            *_line_limits(limits))


def _line_speed(limits, speed_cap, s_from, s_to):
    """Return the speed [m/s] a line's pieces aim at on [s_from, s_to] (limit and cap)."""
    if speed_cap is not None and s_to > s_from:
        return _capped_line_speed(limits, float(_cap_values(
            speed_cap, _even_samples(float(s_from), float(s_to), _LIMIT_SAMPLES)).min()))
    return limits.max_speed * _SPEED_MARGIN


def _capped_line_speed(limits, lowest_cap):
    """Return the speed [m/s] a line aims at where the lowest cap on it is ``lowest_cap``."""
    return min(limits.max_speed * _SPEED_MARGIN, _SPEED_MARGIN * lowest_cap)


def _line_limits(limits):
    """Return the acceleration [m/s**2] and jerk [m/s**3] a line's pieces aim at."""
    return limits.max_accel * _ACCEL_MARGIN, limits.max_jerk * _JERK_MARGIN


def _straight_motion(path, limits, speed_cap, profile):
    """Time a move without an arc (under 1 mm sideways): one straight segment, rest to rest."""
    rows, why = _line_solution((0.0, 0.0, 0.0), (path.length, 0.0, 0.0), limits, speed_cap,
                               0.0, path.length)
    if rows is None:
        raise LimitError('straight move: expected Ruckig to find a rest-to-rest motion, '
                         f'got none for {path.length:.6g} m ({why})')
    pieces = _PieceList()
    pieces.extend(rows)
    law = pieces.law()
    going_up = path.segment_lengths[0] > 0.0
    segments = [law.duration, 0.0, 0.0] if going_up else [0.0, 0.0, law.duration]
    return TimedMotion(path, profile, law.duration, np.array(segments), 0.0, 0.0, None, law)


def _constant_limits(path, s_from, s_to, speed, limits):
    """
    Return (s'' limit, s''' limit) that keep the true limits on [s_from, s_to] at s' <= speed.

    Conservative constants for a Ruckig piece along a curved stretch (worst
    curvature and curvature rate of the stretch, worst case of every term);
    None if there are none.
    """
    s = np.linspace(s_from, s_to, _LIMIT_SAMPLES)
    bend = _bend_length(path)
    if bend is not None and s_from < bend < s_to:
        s = np.sort(np.append(s, bend))
    samples = path.at_lengths(s)
    kappa = np.linalg.norm(samples.curvature, axis=1)
    normal = samples.curvature / np.maximum(kappa, 1e-300)[:, None]
    kappa = float(kappa.max())
    kappa_s = float(np.abs(np.einsum('ij,ij->i', samples.curvature_rate, normal)).max())
    accel, jerk = limits.max_accel * _ACCEL_MARGIN, limits.max_jerk * _JERK_MARGIN
    if kappa * speed * speed >= accel:
        return None
    tangential = math.sqrt(accel ** 2 - (kappa * speed * speed) ** 2)
    if kappa * speed > 0.0:
        tangential = min(tangential, (0.5 * jerk - kappa_s * speed ** 3) / (3.0 * kappa * speed))
    normal_jerk = kappa_s * speed ** 3 + 3.0 * kappa * speed * tangential
    if tangential <= 0.0 or normal_jerk >= jerk:
        return None
    rate = math.sqrt(jerk ** 2 - normal_jerk ** 2) - kappa ** 2 * speed ** 3
    return (tangential, rate) if rate > 0.0 else None


def _bend_length(path):
    """Return the path length [m] of the bend's tightest point, or None without an arc."""
    bend = path.bend
    if bend is None:
        return None
    return float(path.segment_lengths[0] + bend.s_from_t(bend.tightest_t))
