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
The planner's compiled inner loops: numba's nopython mode, one decorator for all of them.

Why a compiler: a whole request has a budget of 3 ms (p50) on a 2-core machine, and CPython
runs some 50-100 million bytecodes a second. The time-optimal scan alone takes ~450 steps
per leg of ~1,200 bytecodes each (issue 11's measurements: a flat float loop, every
per-step evaluation already removed that would change a decision), i.e. ~10 ms per leg
before any check, knot or message. numba is on PyPI for Python 3.11 and 3.12 (manylinux
wheels) and is the rosdep key ``python3-numba`` on Debian and Ubuntu.

Kernels are compiled on first call and cached on disk (numba's cache: beside the module
when that directory is writable, else the user's cache directory), so a process pays the
compilation once per installed version. ``fastmath`` stays off: the kernels do IEEE
arithmetic in the order written, so their results equal the plain-Python ones bit for bit.
``nogil`` lets the node's other callbacks run while a plan is computed. To run every kernel
as the plain Python it is written in (debugging, coverage), set ``NUMBA_DISABLE_JIT=1``.
"""

import dataclasses
import time

import numba

__all__ = ['kernel', 'warm_up']

# The requests that warm_up plans (start, pick, place [m]; the default robot's workspace):
# the paper's example, once per join and per profile, so that every kernel a plan can call is
# called once with the argument types it always gets.
_WARM_UP_REQUEST = ((0.0, 0.0, -0.8), (0.0, 0.0, -0.8), (0.3, 0.0, -0.75))
_WARM_UP_VARIANTS = ({'join': 'g2', 'profile': 'time_optimal'},
                     {'join': 'paper', 'profile': 'time_optimal'},
                     {'join': 'paper', 'profile': 'curvature'})
# Holds True once warm_up has run in this process.
_WARM = []


def kernel(function):
    """
    Compile ``function`` in nopython mode, cached on disk, without the GIL.

    Parameters
    ----------
    function : callable
        Numeric code on floats, ints and NumPy arrays (numba's nopython subset).

    Returns
    -------
    numba.core.registry.CPUDispatcher
        The compiled function; it compiles on its first call for each argument type.

    """
    return numba.njit(cache=True, nogil=True)(function)


def warm_up():
    """
    Compile, or load from numba's cache, every kernel of the planning core before it is needed.

    A kernel compiles on its first call (seconds, or some 0.1 s from the cache): the node calls
    this at start-up so that its first request does not pay for it. It plans the paper's
    example with each join and each profile on the default configuration (the kernels'
    argument types do not depend on it, and a node's own robot or workspace might not reach
    the example).

    Returns
    -------
    float
        Wall-clock time the warm-up took [s]; 0 once a process is warm (every node of a
        process calls it).

    """
    # Imported here: the planner's modules import this one for ``kernel``.
    from . import planner
    if _WARM:
        return 0.0
    started = time.perf_counter()
    config = planner.PlannerConfig()
    start, pick, place = _WARM_UP_REQUEST
    for variant in _WARM_UP_VARIANTS:
        planner.plan_cycle(start, pick, place, dataclasses.replace(config, **variant))
    _WARM.append(True)
    return time.perf_counter() - started
