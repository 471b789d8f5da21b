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
Write config/ellipath.yaml and the README's parameter table from the settings table.

    python3 scripts/settings_docs.py           # rewrite both files
    python3 scripts/settings_docs.py --check   # exit 1 if either is out of step

The table is ``SETTINGS`` in ``ellipath_ros/core/settings.py``; test/test_settings.py checks
that both files are what this script writes.
"""

import argparse
from pathlib import Path
import sys
import textwrap

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ellipath_ros.core.settings import SECTIONS  # noqa: E402 (after the path is set)
from ellipath_ros.core.settings import SETTINGS  # noqa: E402

YAML_PATH = ROOT / 'config' / 'ellipath.yaml'
README_PATH = ROOT / 'README.md'
README_BEGIN = ('<!-- parameter table: generated from ellipath_ros/core/settings.py by '
                'scripts/settings_docs.py, do not edit -->\n')
README_END = '<!-- end of the parameter table -->\n'
WIDTH = 99

YAML_HEADER = """\
# Parameters of ellipath_node, every one at its default. Generated from the settings table
# (ellipath_ros/core/settings.py) by scripts/settings_docs.py; a test keeps them in step.
#   ros2 run ellipath_ros ellipath_node --ros-args --params-file config/ellipath.yaml
# SI units. Ranges: [ and ] include the bound, ( and ) exclude it; every change is checked
# against them and against the other parameters (e.g. joint_min < joint_max).
# Read-only: can only be set at start-up.
/**:
  ros__parameters:
"""


def yaml_value(value):
    """Return ``value`` as YAML flow text (floats keep a dot so that YAML reads a float)."""
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(yaml_value(item) for item in value) + ']'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        text = repr(value)
        mantissa, _, exponent = text.partition('e')
        if '.' not in mantissa:
            mantissa += '.0'
        return mantissa + ('e' + exponent if exponent else '')
    return str(value)


def allowed_text(setting):
    """Return what a setting allows, with its unit: 'range (0, 5] m', 'one of: a, b', ''."""
    unit = f' {setting.unit}' if setting.unit else ''
    if setting.choices:
        return setting.allowed
    if setting.low is None:
        return f'[{setting.unit}]' if setting.unit else ''
    if setting.kind == 'double_array':
        return f'each value in {setting.allowed}{unit}'
    return f'range {setting.allowed}{unit}'


def yaml_comment(setting):
    """Return the lines of the comment above a setting: what it does, allows, read-only."""
    text = setting.description
    # A range is not broken across lines: its ', ' is joined by a NUL until wrapped.
    allowed = allowed_text(setting).replace(setting.allowed,
                                            setting.allowed.replace(', ', ',\0'))
    if allowed.startswith('['):
        text += f' {allowed}.'
    elif allowed:
        text += f'. {allowed[0].upper()}{allowed[1:]}.'
    else:
        text += '.'
    if setting.read_only:
        text += ' Read-only.'
    lines = textwrap.wrap(text, WIDTH - len('    # '), break_on_hyphens=False)
    return [line.replace('\0', ' ') for line in lines]


def render_yaml():
    """Return the text of config/ellipath.yaml."""
    lines = []
    section = None
    for setting in SETTINGS:
        if setting.section != section:
            if section is not None:
                lines.append('')
            section = setting.section
            lines.append(f'    # --- {SECTIONS[section]} ---')
        lines.extend(f'    # {line}' for line in yaml_comment(setting))
        lines.append(f'    {setting.name}: {yaml_value(setting.default)}')
    return YAML_HEADER + '\n'.join(lines) + '\n'


def render_readme_table():
    """Return the README's parameter table, between its markers."""
    rows = ['| name | type | default | unit | allowed | core field | description |',
            '|---|---|---|---|---|---|---|']
    for setting in SETTINGS:
        name = f'`{setting.name}`' + (' (read-only)' if setting.read_only else '')
        field = f'`{setting.owner}.{setting.attribute}`' if setting.owner else 'node'
        allowed = setting.allowed
        if setting.kind == 'double_array' and allowed:
            allowed = f'each value in {allowed}'
        cells = (name, setting.kind, f'`{yaml_value(setting.default)}`', setting.unit, allowed,
                 field, setting.description)
        rows.append('| ' + ' | '.join(cell.replace('|', '\\|') for cell in cells) + ' |')
    return README_BEGIN + '\n'.join(rows) + '\n' + README_END


def readme_with_table(readme):
    """Return ``readme`` with the text between the table's markers replaced by the table."""
    start = readme.index(README_BEGIN)
    end = readme.index(README_END) + len(README_END)
    return readme[:start] + render_readme_table() + readme[end:]


def main(argv=None):
    """Rewrite, or with ``--check`` compare, both files; return the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--check', action='store_true',
                        help='write nothing; exit 1 if a file differs from the table')
    args = parser.parse_args(argv)
    expected = {YAML_PATH: render_yaml(),
                README_PATH: readme_with_table(README_PATH.read_text())}
    stale = [path for path, text in expected.items() if path.read_text() != text]
    if args.check:
        for path in stale:
            sys.stderr.write(f'{path.relative_to(ROOT)}: out of step with the settings table\n')
        return 1 if stale else 0
    for path in stale:
        path.write_text(expected[path])
        sys.stdout.write(f'wrote {path.relative_to(ROOT)}\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
