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
Every Python source carries the Apache-2.0 copyright header.

ament_copyright is not on PyPI, so the header is checked here directly; on a
full ROS 2 install the ament linter runs as well.
"""

import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
HEADER = (ROOT / 'ellipath_ros' / '__init__.py').read_text().split('\n\n')[0]
SOURCES = sorted(
    path for folder in ('ellipath_ros', 'test') for path in (ROOT / folder).rglob('*.py')
) + [ROOT / 'setup.py']


@pytest.mark.copyright
@pytest.mark.linter
@pytest.mark.parametrize('path', SOURCES, ids=lambda path: str(path.relative_to(ROOT)))
def test_header(path):
    assert path.read_text().startswith(HEADER), f'{path}: expected the Apache-2.0 header'


@pytest.mark.copyright
@pytest.mark.linter
def test_header_names_the_license():
    assert 'Copyright' in HEADER and 'Apache License, Version 2.0' in HEADER


@pytest.mark.copyright
@pytest.mark.linter
def test_ament_copyright_when_installed():
    main = pytest.importorskip('ament_copyright.main').main
    assert main(argv=['.', 'test']) == 0, 'Found errors'
