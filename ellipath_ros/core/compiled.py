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
compilation once per installed version. numba keys a kernel's cache on its own source file
only, yet a kernel's compiled code holds every kernel it calls or inlines, from other modules
too: after a change to one module alone (a reinstall, a checkout of another branch), its
callers in the other modules would load their old code. Each kernel's cache is therefore keyed
on every source file of its package as well (:class:`_PackageKeyedCache`).

``fastmath`` stays off: the kernels do IEEE arithmetic in the order written, so their results
equal the plain-Python ones bit for bit. ``nogil`` lets the node's other callbacks run while a
plan is computed. To run every kernel as the plain Python it is written in (debugging,
coverage), set ``NUMBA_DISABLE_JIT=1``.
"""

import dataclasses
import functools
import hashlib
from pathlib import Path
import time

import numba
from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher

from .errors import WorkspaceError

__all__ = ['kernel', 'package_sources_digest', 'warm_up']

# The requests that warm_up plans ((start, pick, place) [m] in the default robot's workspace,
# and the settings changed), so that every kernel a plan calls from Python is called once with
# the argument types it always gets: the paper's example once per join and per profile, and a
# request with a leg whose forward scan alone reaches T2 (its rows are read from Python).
_WARM_UP_REQUESTS = (
    (((0.0, 0.0, -0.8), (0.0, 0.0, -0.8), (0.3, 0.0, -0.75)),
     {'join': 'g2', 'profile': 'time_optimal'}),
    (((0.0, 0.0, -0.8), (0.0, 0.0, -0.8), (0.3, 0.0, -0.75)),
     {'join': 'paper', 'profile': 'time_optimal'}),
    (((0.0, 0.0, -0.8), (0.0, 0.0, -0.8), (0.3, 0.0, -0.75)),
     {'join': 'paper', 'profile': 'curvature'}),
    (((0.0894, 0.1282, -0.6521), (-0.2907, 0.1369, -0.9257), (-0.2663, -0.1060, -0.7932)),
     {'join': 'paper', 'profile': 'time_optimal'}),
    # A transfer whose arc the backward scan alone serves (_Scan.reversed_rows; about 1 leg in
    # 100 on the paper join): its first such leg compiled it in the plan, 0.37 s.
    (((0.0934, 0.0705, -0.6466), (0.0934, 0.0705, -0.6466), (0.1506, 0.0572, -0.8742)),
     {'join': 'paper', 'profile': 'time_optimal'}),
)
# A request whose approach leg crosses a keep-out box (the demo's conveyor rail), planned by
# warm_up and rejected: naming the first executed point outside the workspace calls kernels
# no accepted plan calls (the first such rejection took 9 s in the node without it).
_WARM_UP_REJECTED = (((0.14, 0.08, -0.8), (-0.3, 0.0, -0.9), (0.18, -0.08, -0.83)),
                     (-0.26, -0.3, -1.0, -0.21, 0.3, -0.84))
# Holds True once warm_up has run in this process.
_WARM = []


def kernel(function=None, *, inline=False, zero_divisions=True):
    """
    Compile ``function`` in nopython mode, cached on disk, without the GIL.

    Used bare (``@kernel``) or with options (``@kernel(inline=True)``).

    Parameters
    ----------
    function : callable
        Numeric code on floats, ints and NumPy arrays (numba's nopython subset).
    inline : bool
        Whether kernels calling it get its body inlined (numba's ``inline='always'``,
        before typing) instead of a call: for the small steps a kernel's loop calls hundreds
        of times per plan, where a call (its arguments' reference counts, its error status)
        costs as much as the step. Called from Python it is compiled as any kernel; a kernel
        that inlines it holds a copy of its body (in numba's cache too, as it holds the code
        of every kernel it calls).
    zero_divisions : bool
        Whether a division by zero raises ZeroDivisionError, as in Python (numba's 'python'
        error model), or gives inf or nan, as in NumPy ('numpy'), in this kernel's code and
        the code it inlines. Off only where every divisor is non-zero by construction: a
        raising division is a way out of the kernel, past which numba cannot drop the
        reference counting of the arrays an inlined step takes (see arc_scan's ``_held``).

    Returns
    -------
    numba.core.registry.CPUDispatcher or callable
        The compiled function (it compiles on its first call for each argument type), or,
        without ``function``, the decorator that makes it.

    """
    if function is None:
        return functools.partial(kernel, inline=inline, zero_divisions=zero_divisions)
    compiled = numba.njit(nogil=True, inline='always' if inline else 'never',
                          error_model='python' if zero_divisions else 'numpy')(function)
    if isinstance(compiled, Dispatcher):  # not so under NUMBA_DISABLE_JIT
        # What njit(cache=True) does (Dispatcher.enable_caching), with this module's cache.
        compiled._cache = _PackageKeyedCache(function)
    return compiled


@functools.lru_cache(maxsize=None)
def package_sources_digest(directory):
    """
    Return the SHA-256 digest of every ``*.py`` file in ``directory`` (names and contents).

    Parameters
    ----------
    directory : str
        The directory of a package's modules.

    Returns
    -------
    bytes
        Changes whenever a module of the package is added, removed, renamed or edited.

    """
    digest = hashlib.sha256()
    for path in sorted(Path(directory).glob('*.py')):
        digest.update(path.name.encode() + b'\0' + path.read_bytes() + b'\0')
    return digest.digest()


def _package_keyed(locator_class):
    """Return a subclass of a numba cache locator whose stamp includes the package's sources."""
    def get_source_stamp(self):
        stamp = locator_class.get_source_stamp(self)
        source = getattr(self, '_py_file', None)  # numba's locators of a source file have it
        if source is None or not Path(source).is_file():
            return stamp
        return stamp, package_sources_digest(str(Path(source).parent))

    return type(f'PackageKeyed{locator_class.__name__}', (locator_class,),
                {'get_source_stamp': get_source_stamp})


class _PackageKeyedCacheImpl(FunctionCache._impl_class):
    """numba's cache implementation with every locator keyed on the package's sources."""

    _locator_classes = [_package_keyed(locator_class)
                        for locator_class in FunctionCache._impl_class._locator_classes]


class _PackageKeyedCache(FunctionCache):
    """
    numba's on-disk cache of a kernel, invalid as soon as any module of its package changes.

    numba compares the stamp stored in a cache index with the current one and discards the
    index when they differ; the stamp here pairs numba's own (the kernel's file) with
    :func:`package_sources_digest` of the kernel's package directory, read once per process.
    """

    _impl_class = _PackageKeyedCacheImpl


def warm_up():
    """
    Compile, or load from numba's cache, every kernel of the planning core before it is needed.

    A kernel compiles on its first call (seconds, or some 0.1 s from the cache): the node calls
    this at start-up so that its first request does not pay for it. It plans a few requests
    (``_WARM_UP_REQUESTS``) on the default configuration (the kernels' argument types do not
    depend on it, and a node's own robot or workspace might not reach them), and one that the
    executed workspace check rejects (``_WARM_UP_REJECTED``).

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
    for (start, pick, place), settings in _WARM_UP_REQUESTS:
        planner.plan_cycle(start, pick, place, dataclasses.replace(config, **settings))
    (start, pick, place), box = _WARM_UP_REJECTED
    crossed = dataclasses.replace(config, workspace=dataclasses.replace(
        config.workspace, keep_out_boxes=(box,)))
    try:
        planner.plan_cycle(start, pick, place, crossed)
    except WorkspaceError:
        pass  # The rejection is what this request is for.
    _WARM.append(True)
    return time.perf_counter() - started
