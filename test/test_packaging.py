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
Packaging: package.xml's dependencies, the launch file and the install layout.

``launch`` is not installable here: the launch file is compiled and run
against stand-ins for ``launch`` and ``launch_ros`` that record what it
builds; setup.py is run with a recording ``setuptools.setup``. ``make colcon``
(in CI) checks the real install.
"""

import ast
import pathlib
import runpy
import sys
import types
import xml.etree.ElementTree as ElementTree

import setuptools

ROOT = pathlib.Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / 'launch' / 'ellipath.launch.py'


class _Recorded:
    """Stand-in for a launch entity: keeps its arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _setup_arguments(monkeypatch):
    recorded = {}
    monkeypatch.setattr(setuptools, 'setup', lambda **kwargs: recorded.update(kwargs))
    monkeypatch.chdir(ROOT)
    runpy.run_path(str(ROOT / 'setup.py'), run_name='__main__')
    return recorded


def test_launch_file_compiles():
    source = LAUNCH_FILE.read_text()
    compile(source, str(LAUNCH_FILE), 'exec')
    functions = [node.name for node in ast.walk(ast.parse(source))
                 if isinstance(node, ast.FunctionDef)]
    assert 'generate_launch_description' in functions


def test_launch_file_starts_the_node_with_the_installed_config(monkeypatch, tmp_path):
    share = tmp_path / 'share' / 'ellipath_ros'
    packages = types.ModuleType('ament_index_python.packages')
    packages.get_package_share_directory = (
        lambda name: str(share) if name == 'ellipath_ros' else None)
    launch = types.ModuleType('launch')
    launch.LaunchDescription = _Recorded
    actions = types.ModuleType('launch.actions')
    actions.DeclareLaunchArgument = _Recorded
    substitutions = types.ModuleType('launch.substitutions')
    substitutions.LaunchConfiguration = _Recorded
    launch_ros = types.ModuleType('launch_ros')
    ros_actions = types.ModuleType('launch_ros.actions')
    ros_actions.Node = _Recorded
    for name, module in (('ament_index_python.packages', packages), ('launch', launch),
                         ('launch.actions', actions), ('launch.substitutions', substitutions),
                         ('launch_ros', launch_ros), ('launch_ros.actions', ros_actions)):
        monkeypatch.setitem(sys.modules, name, module)

    description = runpy.run_path(str(LAUNCH_FILE))['generate_launch_description']()

    entities = description.args[0]
    arguments = {entity.args[0]: entity.kwargs['default_value']
                 for entity in entities if 'default_value' in entity.kwargs}
    assert arguments['params_file'] == str(share / 'config' / 'ellipath.yaml')
    assert (ROOT / 'config' / 'ellipath.yaml').is_file()
    nodes = [entity for entity in entities if 'executable' in entity.kwargs]
    assert len(nodes) == 1
    node = nodes[0].kwargs
    assert (node['package'], node['executable']) == ('ellipath_ros', 'ellipath_node')
    assert [parameter.args for parameter in node['parameters']] == [('params_file',)]
    scripts = _setup_arguments(monkeypatch)['entry_points']['console_scripts']
    assert any(script.startswith('ellipath_node = ') for script in scripts)


def test_setup_installs_the_launch_file_and_has_no_tests_require(monkeypatch):
    arguments = _setup_arguments(monkeypatch)
    data_files = dict(arguments['data_files'])
    assert data_files['share/ellipath_ros/launch'] == ['launch/ellipath.launch.py']
    assert 'tests_require' not in arguments


def _imported_top_level_modules(path):
    modules = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            modules.update(alias.name.split('.')[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            modules.add(node.module.split('.')[0])
    return modules


def test_package_xml_declares_every_ros_package_imported():
    sources = list((ROOT / 'ellipath_ros').rglob('*.py')) + list((ROOT / 'launch').glob('*.py'))
    imported = set().union(*(_imported_top_level_modules(path) for path in sources))
    ros_suffixes = ('_msgs', '_srvs', '_interfaces')
    ros_names = {'rclpy', 'launch', 'launch_ros', 'ament_index_python'}
    ros_imports = {name for name in imported
                   if name in ros_names or name.endswith(ros_suffixes)}
    assert {'rclpy', 'rcl_interfaces', 'trajectory_msgs', 'launch_ros'} <= ros_imports
    declared = {element.text for element in ElementTree.parse(ROOT / 'package.xml').getroot()
                if element.tag in ('exec_depend', 'depend')}
    assert ros_imports <= declared, sorted(ros_imports - declared)
    assert 'numpy' in imported and 'python3-numpy' in declared
