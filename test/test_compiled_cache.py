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

"""The kernels' disk cache: a kernel's cached code is dropped when a module it calls changes."""

import os
from pathlib import Path
import subprocess
import sys
import textwrap

from ellipath_ros.core.compiled import package_sources_digest
import pytest

# A package of two modules: ``outer`` (in outer.py) calls ``inner`` (in inner.py), whose
# compiled code numba puts into outer's; both compiled by ``decorator``, imported as ``name``
# from ``module``.
INNER = textwrap.dedent("""
    from {module} import {name}

    @{decorator}
    def inner(x):
        return x + {value}
""")
OUTER = textwrap.dedent("""
    from {module} import {name}
    from .inner import inner

    @{decorator}
    def outer(x):
        return 2.0 * inner(x)
""")
# Prints outer(1.0) and how many of outer's compiled forms this process loaded from the cache.
RUN = ('from kernels.outer import outer; value = outer(1.0); '
       'print(value, sum(outer.stats.cache_hits.values()))')


def _write_package(root, module, name, decorator, value):
    package = root / 'kernels'
    package.mkdir(exist_ok=True)
    (package / '__init__.py').write_text('')
    names = {'module': module, 'name': name, 'decorator': decorator, 'value': value}
    (package / 'inner.py').write_text(INNER.format(**names))
    (package / 'outer.py').write_text(OUTER.format(**names))


def _outer_of_one(root):
    """Return (outer(1.0), forms loaded from the cache) in a fresh interpreter."""
    environment = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(root), *filter(None, [os.environ.get('PYTHONPATH')])])}
    environment.pop('NUMBA_CACHE_DIR', None)  # the cache beside the modules (in-tree)
    environment.pop('NUMBA_DISABLE_JIT', None)
    result = subprocess.run([sys.executable, '-c', RUN], capture_output=True, text=True,
                            cwd=root, env=environment, timeout=120, check=True)
    value, hits = result.stdout.split()
    return float(value), int(hits)


@pytest.mark.parametrize('module, name, decorator, stale', [
    ('ellipath_ros.core.compiled', 'kernel', 'kernel', False),
    # numba's own cache, for contrast: this is the failure the kernel decorator prevents.
    ('numba', 'njit', 'njit(cache=True)', True),
])
def test_a_change_to_a_called_module_alone_recompiles_its_callers(
        tmp_path, module, name, decorator, stale):
    _write_package(tmp_path, module, name, decorator, 1.0)
    assert _outer_of_one(tmp_path) == (4.0, 0)  # compiled
    assert _outer_of_one(tmp_path) == (4.0, 1)  # loaded from the cache
    # Only inner.py changes; outer.py, whose cache holds inner's old code, stays as it was.
    inner = tmp_path / 'kernels' / 'inner.py'
    inner.write_text(inner.read_text().replace('x + 1.0', 'x + 3.0'))
    assert _outer_of_one(tmp_path) == ((4.0, 1) if stale else (8.0, 0))


def test_the_digest_covers_every_module_of_the_directory(tmp_path):
    for name in ('a.py', 'b.py'):
        (tmp_path / name).write_text(f'# {name}\n')
    (tmp_path / 'notes.txt').write_text('not a module')
    first = package_sources_digest.__wrapped__(str(tmp_path))
    (tmp_path / 'notes.txt').write_text('changed, still not a module')
    assert package_sources_digest.__wrapped__(str(tmp_path)) == first
    (tmp_path / 'b.py').write_text('# b, edited\n')
    edited = package_sources_digest.__wrapped__(str(tmp_path))
    assert edited != first
    (tmp_path / 'b.py').rename(tmp_path / 'c.py')
    assert package_sources_digest.__wrapped__(str(tmp_path)) not in (first, edited)
    assert Path(tmp_path / 'c.py').exists()
