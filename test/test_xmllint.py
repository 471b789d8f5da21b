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
package.xml is well-formed format 3 with what an ament_python package needs.

ament_xmllint (schema validation) is not on PyPI; the structure is checked
here directly and the ament linter runs as well where it is installed.
"""

import pathlib
import xml.etree.ElementTree as ElementTree

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.mark.linter
@pytest.mark.xmllint
def test_package_xml_structure():
    package = ElementTree.parse(ROOT / 'package.xml').getroot()
    assert package.tag == 'package' and package.get('format') == '3'
    assert package.findtext('name') == 'ellipath_ros'
    for tag in ('version', 'description', 'maintainer', 'license'):
        assert (package.findtext(tag) or '').strip(), f'package.xml: missing <{tag}>'
    assert package.find('maintainer').get('email')
    assert package.findtext('export/build_type') == 'ament_python'
    for dependency in ('rclpy', 'geometry_msgs', 'trajectory_msgs', 'sensor_msgs',
                       'diagnostic_msgs', 'visualization_msgs'):
        assert dependency in [element.text for element in package.iter('exec_depend')]


@pytest.mark.linter
@pytest.mark.xmllint
def test_version_matches_setup():
    package = ElementTree.parse(ROOT / 'package.xml').getroot()
    assert f"version='{package.findtext('version')}'" in (ROOT / 'setup.py').read_text()


@pytest.mark.linter
@pytest.mark.xmllint
def test_ament_xmllint_when_installed():
    main = pytest.importorskip('ament_xmllint.main').main
    assert main(argv=[]) == 0, 'Found errors'
