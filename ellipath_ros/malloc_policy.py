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
glibc's malloc policy of the ``ellipath_node`` process, and giving its free pages back.

Standard library only, so that the ``ellipath_node`` command (:mod:`ellipath_ros.node_entry`)
sets the policy before it imports rclpy, whose import already starts threads that allocate
(docs/reliability.md, "Where the node's memory grows"). Nothing here runs on import.
"""

import ctypes
import os

__all__ = ['MALLOC_ARENA_MAX', 'MALLOC_ENVIRONMENT', 'MALLOC_MMAP_THRESHOLD',
           'MALLOC_TRIM_PERIOD', 'MALLOC_TRIM_THRESHOLD', 'release_free_memory',
           'set_malloc_policy']

# By default glibc gives every thread that allocates an arena of its own (up to 8 per core;
# the node has about 20 threads), each arena keeps what was freed in it, and the mmap
# threshold rises to the largest block freed so far (mallopt(3)), so that NumPy's large
# temporaries come from the arenas instead of being mapped and unmapped. Under continuous
# pairs the node's resident memory kept rising while the memory in use (mallinfo2) did not:
# it was memory freed and kept. One arena: malloc_trim(0) gives back the free top of the main
# arena only, while the free top of another arena's heap goes back only when a free() leaves
# it above the trim threshold; with a second arena the node's memory stepped up by 0.7 MiB
# in a 30-minute soak and stayed there (docs/reliability.md, "Where the node's memory
# grows"). One arena is what the planning thread, which does nearly all the allocating, uses
# anyway; the DDS and executor threads allocate little.
# The thresholds set what a plan pays in page faults: a block above the mmap threshold is
# mapped and its pages faulted in at each use, and free memory above the trim threshold
# (128 KiB unless set) at an arena's top is given back after each free, to be faulted in
# again by the next plan. At 256 KiB and 128 KiB a default plan took 200-800 minor faults and
# up to 8 ms of system time (64 KiB: 14 ms); at 2 MiB and 8 MiB none at the median, 3 at p90
# (NumPy's largest temporaries of a default plan stay below 2 MiB), with 7 MiB kept free
# after a plan instead of 2.5.
MALLOC_ARENA_MAX = 1
MALLOC_MMAP_THRESHOLD = 2 * 1024 * 1024  # bytes
MALLOC_TRIM_THRESHOLD = 8 * 1024 * 1024  # bytes
# mallopt() parameters (glibc's malloc.h).
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8
# Environment variables with which the caller sets glibc's malloc policy: theirs prevails.
MALLOC_ENVIRONMENT = ('MALLOC_ARENA_MAX', 'MALLOC_MMAP_THRESHOLD_', 'MALLOC_TRIM_THRESHOLD_',
                      'GLIBC_TUNABLES')
# The planning thread gives glibc's free pages back (release_free_memory) after a plan at
# most once per this period [s], not after every plan: the plan after a trim faults in again
# every page it uses (about 800 minor faults, 4 ms of system time and as much user time,
# a third of a default plan's CPU), and the node planned each pair after idle time 35 ms
# against 21 in a loop. Once a minute still bounds what the arena keeps.
MALLOC_TRIM_PERIOD = 60.0


def set_malloc_policy(environment=os.environ):
    """
    Limit glibc's malloc arenas and fix its mmap and trim thresholds; return True if set.

    Nothing is changed off glibc (no ``mallopt``, or not glibc's) or when the caller chose a
    policy in ``environment`` (see MALLOC_ENVIRONMENT). Call it before any thread but the
    main one allocates: an arena, once created, stays (importing rclpy makes two), and later
    threads share the arenas there are.
    """
    if any(name in environment for name in MALLOC_ENVIRONMENT):
        return False
    try:
        if not os.confstr('CS_GNU_LIBC_VERSION'):
            return False
        mallopt = ctypes.CDLL(None).mallopt
    except (AttributeError, OSError, ValueError):
        return False  # not glibc: its allocator has no such arenas
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    return bool(mallopt(_M_ARENA_MAX, MALLOC_ARENA_MAX)
                and mallopt(_M_MMAP_THRESHOLD, MALLOC_MMAP_THRESHOLD)
                and mallopt(_M_TRIM_THRESHOLD, MALLOC_TRIM_THRESHOLD))


def release_free_memory():
    """
    Give the free pages of glibc's arenas back to the system (malloc_trim(0)); off glibc, none.

    Called after a plan, at most once per MALLOC_TRIM_PERIOD: the arena otherwise keeps what
    a plan freed behind blocks still in use, and the node's resident memory crept up by about
    50 KiB a minute at 1 pair/s (docs/reliability.md, "The node over time"). About 0.4 ms of
    CPU, and the next plan faults in again the pages given back.
    """
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


def _glibc_malloc_trim():
    """Return glibc's malloc_trim, or None off glibc."""
    try:
        if not os.confstr('CS_GNU_LIBC_VERSION'):
            return None
        malloc_trim = ctypes.CDLL(None).malloc_trim
    except (AttributeError, OSError, ValueError):
        return None
    malloc_trim.argtypes = (ctypes.c_size_t,)
    return malloc_trim


_MALLOC_TRIM = _glibc_malloc_trim()
