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

import numba

__all__ = ['kernel']


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
