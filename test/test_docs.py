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
"""The documentation as a new user meets it: every link resolves, commands have no placeholders."""

import pathlib
import re
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAGES = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]
# ![alt](target) and [text](target), without the #fragment; web links are not checked.
LINK = re.compile(r'!?\[[^\]]*\]\(([^)#\s]+)(?:#[^)]*)?\)')


def _tracked_files():
    """Return the repository's tracked files, or None outside a git checkout."""
    try:
        listing = subprocess.run(['git', 'ls-files', '-z'], cwd=ROOT, capture_output=True,
                                 check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    return {ROOT / name for name in listing.decode().split('\0') if name}


@pytest.mark.parametrize('page', PAGES, ids=lambda page: page.name)
def test_every_local_link_and_image_resolves_to_a_tracked_file(page):
    targets = [target for target in LINK.findall(page.read_text())
               if not re.match(r'[a-z]+://', target)]
    images = re.findall(r'!\[[^\]]*\]\(([^)\s]+)\)', page.read_text())
    if page.name in ('README.md', 'paper_reproduction.md'):
        assert images, page
    tracked = _tracked_files()
    for target in targets:
        path = (page.parent / target).resolve()
        assert path.exists(), f'{page.name}: {target} does not exist'
        if tracked is not None and path.is_file():
            assert path in tracked, f'{page.name}: {target} is not committed'


def test_readme_commands_have_no_placeholders():
    blocks = re.findall(r'```bash\n(.*?)```', (ROOT / 'README.md').read_text(), re.S)
    assert blocks
    for block in blocks:
        for line in block.splitlines():
            command = line.split('  #')[0]
            assert '...' not in command and not re.search(r'<[a-z ]+>', command), line
