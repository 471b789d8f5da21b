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
Sample the memory of ``ellipath_node`` from inside it (an experiment, docs/reliability.md).

Python imports ``sitecustomize`` at start-up from the path: with this directory on
``PYTHONPATH`` and ``ELLIPATH_MEMORY_PROBE`` naming a file, a process started as
``python -m ellipath_ros.node_entry`` (as scripts/flood.py and scripts/soak.py start it) or
``python -m ellipath_ros.node`` writes a
JSON line every ``ELLIPATH_MEMORY_PROBE_PERIOD`` seconds (default 20): VmRSS by kind of
mapping (``[heap]`` is glibc's main arena; ``anon`` its other arenas, Python's and large
mapped blocks; ``file`` the libraries; ``shm`` Fast DDS's shared memory), glibc's
``mallinfo2`` over every arena (``in_use``: allocated; ``kept``: freed but kept by the
allocator; ``mapped``: blocks mapped on their own), the Python heap's blocks, the number of
threads and, with ``NUMBA_NRT_STATS=1``, numba's runtime allocations still live (allocated
less freed: the arrays that compiled kernels create, which neither the Python heap nor
tracemalloc sees). With ``ELLIPATH_MEMORY_PROBE_TRACE`` set to a number of seconds,
tracemalloc starts then (after the warm-up; it slows the node several times) and every sample
adds the 8 source lines whose allocations still held grew most since the first sample after
it. Other processes are not touched::

    PYTHONPATH=scripts/memory_probe ELLIPATH_MEMORY_PROBE=/tmp/probe.jsonl \
        ROS_DOMAIN_ID=45 .venv/bin/python scripts/soak.py node --minutes 8 --rate 3

(No ``gc.get_objects()`` here: a list of every object, taken from another thread, can catch a
tuple that ``tuple()`` is still building, which then fails with a SystemError.)
"""

import ctypes
import json
import os
import sys
import threading
import time
import tracemalloc


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        'arena', 'ordblks', 'smblks', 'hblks', 'hblkhd', 'usmblks', 'fsmblks', 'uordblks',
        'fordblks', 'keepcost')]


def _is_the_node():
    try:
        with open('/proc/self/cmdline', 'rb') as cmdline:
            arguments = cmdline.read().split(b'\0')
            return b'ellipath_ros.node' in arguments or b'ellipath_ros.node_entry' in arguments
    except OSError:
        return False


def _resident_by_kind():
    """Return the resident memory [KiB] of this process by kind of mapping."""
    kinds = {}
    kind = None
    with open('/proc/self/smaps') as smaps:
        for line in smaps:
            fields = line.split()
            if fields[0] == 'Rss:':
                kinds[kind] = kinds.get(kind, 0) + int(fields[1])
            elif '-' in fields[0] and not fields[0].endswith(':'):
                path = fields[5] if len(fields) > 5 else ''
                kind = ('anon' if not path else 'shm' if path.startswith('/dev/shm')
                        else path if path.startswith('[') else 'file')
    return kinds


def _stack_pointers():
    """Return {thread name: stack pointer} of this process's blocked threads (task/*/syscall)."""
    pointers = {}
    for task in os.listdir('/proc/self/task'):
        try:
            with open(f'/proc/self/task/{task}/comm') as comm:
                name = f'{comm.read().strip()}:{task}'
            with open(f'/proc/self/task/{task}/syscall') as syscall:
                fields = syscall.read().split()
        except OSError:
            continue
        if len(fields) >= 3 and fields[0] != 'running':
            pointers[name] = int(fields[-2], 16)
    return pointers


def _anonymous_maps():
    """
    Return [[start, size KiB, Rss KiB, permissions, what]] of the anonymous mappings with Rss.

    ``what`` names a thread whose stack pointer lies in the mapping, ``arena?`` for a mapping
    aligned as glibc aligns its non-main arenas' heaps (64 MiB), else ''.
    """
    pointers = _stack_pointers()
    maps = []
    current = None
    with open('/proc/self/smaps') as smaps:
        for line in smaps:
            fields = line.split()
            if '-' in fields[0] and not fields[0].endswith(':'):
                current = None
                if len(fields) <= 5:
                    start, end = (int(value, 16) for value in fields[0].split('-'))
                    what = ','.join(name for name, pointer in pointers.items()
                                    if start <= pointer < end)
                    if not what and start % (64 << 20) == 0:
                        what = 'arena?'
                    current = [hex(start), (end - start) // 1024, 0, fields[1], what]
                    maps.append(current)
            elif fields[0] == 'Rss:' and current is not None:
                current[2] = int(fields[1])
    return [row for row in maps if row[2]]


def _numba_live():
    """Return numba's runtime allocations and meminfos still live, if it counts them."""
    runtime = sys.modules.get('numba.core.runtime')
    if runtime is None or os.environ.get('NUMBA_NRT_STATS') != '1':
        return None
    stats = runtime.rtsys.get_allocation_stats()
    return {'allocations': stats.alloc - stats.free, 'meminfos': stats.mi_alloc - stats.mi_free}


def _sample(mallinfo2, started):
    info = mallinfo2()
    return {'t': round(time.monotonic() - started), 'resident_kib': _resident_by_kind(),
            'in_use_kib': info.uordblks // 1024, 'kept_kib': info.fordblks // 1024,
            'mapped_kib': info.hblkhd // 1024, 'python_blocks': sys.getallocatedblocks(),
            'threads': len(os.listdir('/proc/self/task')), 'numba_live': _numba_live(),
            'anonymous_maps': _anonymous_maps() if os.environ.get(
                'ELLIPATH_MEMORY_PROBE_MAPS') == '1' else None}


def _traced_growth(snapshot, first):
    """Return the 8 source lines whose held allocations grew most since ``first``."""
    return [{'where': str(stat.traceback[0]), 'size_diff_b': stat.size_diff,
             'count_diff': stat.count_diff, 'size_b': stat.size}
            for stat in snapshot.compare_to(first, 'lineno')[:8]]


def _probe(path, period, trace_after):
    mallinfo2 = ctypes.CDLL(None).mallinfo2
    mallinfo2.restype = _Mallinfo2
    started = time.monotonic()
    first_trace = None
    with open(path, 'w') as out:
        while True:
            time.sleep(period)
            sample = _sample(mallinfo2, started)
            if trace_after is not None and sample['t'] >= trace_after:
                if not tracemalloc.is_tracing():
                    tracemalloc.start()
                elif first_trace is None:
                    first_trace = tracemalloc.take_snapshot()
                else:
                    sample['traced_growth'] = _traced_growth(tracemalloc.take_snapshot(),
                                                             first_trace)
            out.write(json.dumps(sample) + '\n')
            out.flush()


if os.environ.get('ELLIPATH_MEMORY_PROBE') and _is_the_node():
    threading.Thread(target=_probe, name='memory_probe', daemon=True, args=(
        os.environ['ELLIPATH_MEMORY_PROBE'],
        float(os.environ.get('ELLIPATH_MEMORY_PROBE_PERIOD', '20')),
        float(os.environ['ELLIPATH_MEMORY_PROBE_TRACE'])
        if os.environ.get('ELLIPATH_MEMORY_PROBE_TRACE') else None)).start()
