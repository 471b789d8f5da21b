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
Timing laws along a :class:`~ellipath_ros.core.geometry.PickPlacePath`: one entry point.

Two profiles (:func:`time_motion`): ``curvature``, the paper's (section 2.3,
:mod:`~ellipath_ros.core.curvature_profile`), and ``time_optimal``, beyond
the paper (:mod:`~ellipath_ros.core.optimal_profile`). Both return a
:class:`~ellipath_ros.core.motion.TimedMotion`. The constructions aim at a
margin below the limits (:mod:`~ellipath_ros.core.limits`); the result is then
sampled (on the samples of its metrics, which follow the law's pieces: at most
0.2 ms apart and both sides of every piece bound) and, should a limit or the
speed cap be broken there after all, slowed down uniformly in time until it is
not.
"""

import math

import numpy as np

from .curvature_profile import _curvature_motion
from .errors import InvalidInputError, require_range
from .geometry import PickPlacePath
from .limits import _cap_values, CartesianLimits
from .motion import _sampled, PROFILES
from .optimal_profile import _optimal_motion

# When the final limit check finds a limit broken, it measures again around the samples
# within _SAFETY_WINDOW of breaking one (as a share of the slow-down each needs), with
# _SAFETY_REFINE times as many samples there, and adds _SAFETY_SLACK to the slow-down.
# The window lies above every share the constructions aim at (the speed's 0.999 is the
# closest, 1 - 1e-3), so that their long stretches at the targets are not sampled again;
# what it leaves out is at least that far below a limit on the samples.
_SAFETY_WINDOW = 5e-4
_SAFETY_REFINE = 8
_SAFETY_SLACK = 2e-3
_SAFETY_NARROW = 1e-6


def _within_limits(motion, limits, speed_cap):
    """
    Return ``motion``, slowed down uniformly if sampling finds a limit broken.

    The motion is sampled as its metrics are (:meth:`TimedMotion.sampled_norms`,
    which keeps the peaks for them, each refined between its samples). A
    construction that breaks a limit has missed something sharp (a bend
    tighter than its tables), within a few samples of a peak: the factor is
    then measured again between the neighbours of every sample within
    ``_SAFETY_WINDOW`` of breaking a limit, ``_SAFETY_REFINE`` times as densely,
    and given ``_SAFETY_SLACK`` on top, for what falls between even those samples.
    """
    s, speed, accel, jerk = motion.sampled_norms()
    factor = _excess(s, speed, motion._peaks, limits, speed_cap)
    if factor <= 1.0:
        return motion
    needed = np.maximum.reduce([
        speed / limits.max_speed, np.sqrt(accel / limits.max_accel),
        np.cbrt(jerk / limits.max_jerk)])
    if speed_cap is not None:
        needed = np.maximum(needed, speed / _cap_values(speed_cap, s))
    times = _around(motion.sampled_states()[0], needed >= 1.0 - _SAFETY_WINDOW)
    s, _, norms, peaks = _sampled(motion, times)
    factor = max(factor, _excess(s, norms[0], peaks, limits, speed_cap))
    return motion.scaled(factor * (1.0 + _SAFETY_SLACK))


def _around(t, close):
    """
    Return sorted times between the neighbours of each sample of ``t`` (N,) marked ``close``.

    ``_SAFETY_REFINE`` even steps across each interval next to a marked sample, its
    ends included; an interval shorter than ``_SAFETY_NARROW`` of the span of ``t``
    (the two samples just off a piece bound) only by its ends: three samples within
    rounding of a bound would refine a step of the path's curvature there as a peak.
    """
    marked = np.flatnonzero(close)
    starts = np.unique(np.concatenate((marked - 1, marked)).clip(0, t.size - 2))
    steps = np.arange(_SAFETY_REFINE + 1) / _SAFETY_REFINE
    widths = t[starts + 1] - t[starts]
    widths[widths < _SAFETY_NARROW * (t[-1] - t[0])] = 0.0
    return np.unique(np.concatenate((t[starts, None] + widths[:, None] * steps,
                                     t[starts + 1, None]), axis=None))


def _excess(s, speed, peaks, limits, speed_cap):
    """
    Return the uniform slow-down that brings the motion within the limits (>= 0).

    ``peaks`` are the largest speed, acceleration and jerk norms (three
    floats); the speed cap is read at the samples' path lengths ``s`` and
    speeds ``speed`` (N,).
    """
    peak_speed, peak_accel, peak_jerk = peaks
    factor = max(peak_speed / limits.max_speed, math.sqrt(peak_accel / limits.max_accel),
                 (peak_jerk / limits.max_jerk) ** (1.0 / 3.0))
    if speed_cap is not None:
        factor = max(factor, float((speed / _cap_values(speed_cap, s)).max()))
    return factor


def time_motion(path, limits=None, profile='time_optimal', r=0.77, speed_cap=None):
    """
    Time a pick-and-place path.

    Parameters
    ----------
    path : PickPlacePath
        The path (:func:`~ellipath_ros.core.geometry.plan_path`).
    limits : CartesianLimits, optional
        Defaults when omitted.
    profile : str
        ``'time_optimal'`` (default) or ``'curvature'`` (the paper's).
    r : float
        The paper's proportionality coefficient [rad/m], > 0 (curvature only).
    speed_cap : callable, optional
        ``speed_cap(s)`` -> largest s' [m/s] at path lengths ``s`` (N,), an
        array of shape (N,), positive; e.g. from joint velocity limits.

    Returns
    -------
    TimedMotion

    Raises
    ------
    InvalidInputError
        Unknown profile, r <= 0, a bad path, limits or speed cap.
    LimitError
        No motion within the limits was found (not expected with positive
        limits; the slow fallback below always finds one).

    Notes
    -----
    ``time_optimal``: the vertical segments are straight, so Ruckig times them
    exactly (from rest to the arc's entry state, from its exit state to rest).
    Entry and exit speeds are the largest the acceleration step, the
    curvature, the cap and the clearance allow, with s'' = 0 there, except
    at a G2 end, where the lift may still brake into the arc (the descent
    start still speed up) if a probe finds that faster. On the
    arc, a scan integrates s''' in steps of ``_SCAN_STEP`` (shorter on tight
    curvature) forwards from T1 and, mirrored, backwards from T2. Each step
    takes the largest jerk legal at both of its ends, aims s'' at the largest
    value the state allows (acceleration norm, and the normal jerk
    3 kappa v s'' + kappa_s v**3 within a share of the budget, negative where
    the curvature tightens too fast) and levels s'' off below the speed limit
    and the cap, which is read as stairs so that two scans cruising on one
    stair meet. Where the aim falls faster than the jerk can follow, the scan
    backs up and aims lower there. The slower scan advances until the two
    speed curves cross; one constant-jerk piece, solved for continuity of s,
    s', s'' at both ends (Newton, then bracketing), joins them. Where they
    cannot meet (a speed valley inside the arc: a tight bend or a dip of the
    cap), the arc is split at the lowest ceiling and each part solved the
    same way; an end speed the arc cannot take comes down. If all that
    fails, a sure but slow construction (Ruckig pieces between knots, each
    with constant limits valid on its stretch) is used.

    """
    if not isinstance(path, PickPlacePath):
        raise InvalidInputError(f'path: expected a PickPlacePath, got {type(path).__name__}')
    limits = CartesianLimits() if limits is None else limits
    if not isinstance(limits, CartesianLimits):
        raise InvalidInputError(
            f'limits: expected a CartesianLimits, got {type(limits).__name__}')
    if profile not in PROFILES:
        raise InvalidInputError(
            f'profile: expected one of {", ".join(PROFILES)}, got {profile!r}')
    r = require_range('r', r, 0.0, math.inf, low_open=True, unit='rad/m')
    if speed_cap is not None and not callable(speed_cap):
        raise InvalidInputError(
            f'speed_cap: expected a callable or None, got {type(speed_cap).__name__}')
    if profile == 'curvature':
        if path.join != 'paper':
            raise InvalidInputError(
                f'join: expected paper with the curvature profile (its node rule is the '
                f"paper's, on the ellipse), got {path.join!r}")
        motion = _curvature_motion(path, limits, r, speed_cap)
    else:
        motion = _optimal_motion(path, limits, speed_cap)
    return _within_limits(motion, limits, speed_cap)
