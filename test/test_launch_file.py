"""launch/selector.launch.py: parses, declares its arguments, and builds the selector node.

``launch`` and ``launch_ros`` are not on PyPI, so the file is read with ``ast`` and run against
small recording stand-ins of the few classes it uses (installation: test_colcon_layout.py).
"""

from __future__ import annotations

import ast
import runpy
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAUNCH_FILE = ROOT / 'launch' / 'selector.launch.py'
ARGUMENTS = {'namespace', 'image', 'camera_info', 'params_file'}


def test_launch_file_parses_and_declares_generate_launch_description():
    tree = ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert 'generate_launch_description' in functions
    imported = {
        alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom)
        for alias in node.names
    }
    assert {'DeclareLaunchArgument', 'LaunchConfiguration', 'Node', 'FindPackageShare'} <= (
        imported
    )
    names = {
        elt.elts[0].value
        for node in ast.walk(tree)
        if isinstance(node, ast.Assign)
        and any(getattr(t, 'id', '') == 'ARGUMENTS' for t in node.targets)
        for elt in node.value.elts
    }
    assert names == ARGUMENTS


class _Recorder:
    """Stands in for a launch class: keeps its arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _Configuration(_Recorder):
    def __eq__(self, other):
        return isinstance(other, _Configuration) and self.args == other.args

    __hash__ = None


@pytest.fixture
def launch_stand_ins(monkeypatch):
    modules = {
        'launch': {'LaunchDescription': type('LaunchDescription', (_Recorder,), {})},
        'launch.actions': {
            'DeclareLaunchArgument': type('DeclareLaunchArgument', (_Recorder,), {})
        },
        'launch.substitutions': {
            'LaunchConfiguration': _Configuration,
            'PathJoinSubstitution': type('PathJoinSubstitution', (_Recorder,), {}),
        },
        'launch_ros': {},
        'launch_ros.actions': {'Node': type('Node', (_Recorder,), {})},
        'launch_ros.substitutions': {
            'FindPackageShare': type('FindPackageShare', (_Recorder,), {})
        },
    }
    for name, attributes in modules.items():
        module = types.ModuleType(name)
        module.__dict__.update(attributes)
        monkeypatch.setitem(sys.modules, name, module)


def test_launch_description_has_the_arguments_and_the_selector_node(launch_stand_ins):
    description = runpy.run_path(str(LAUNCH_FILE))['generate_launch_description']()
    *declared, node = description.args[0]
    assert {d.args[0] for d in declared} == ARGUMENTS
    defaults = {d.args[0]: d.kwargs['default_value'] for d in declared}
    assert defaults['namespace'] == '' and defaults['image'] == 'image_raw'
    share = defaults['params_file'].args[0]
    assert share[0].args == ('initsel_ros',) and share[1:] == ['config', 'selector.yaml']
    assert all(d.kwargs['description'] for d in declared)
    assert node.kwargs['package'] == 'initsel_ros' and node.kwargs['executable'] == 'selector'
    assert node.kwargs['name'] == 'selector'
    assert node.kwargs['namespace'] == _Configuration('namespace')
    assert node.kwargs['parameters'] == [_Configuration('params_file')]
    assert dict(node.kwargs['remappings']) == {
        'image_raw': _Configuration('image'),
        'camera_info': _Configuration('camera_info'),
    }


def test_setup_installs_the_launch_files_into_share():
    setup = (ROOT / 'setup.py').read_text()
    assert "(f'share/{package_name}/launch', sorted(glob('launch/*.launch.py')))" in setup
    assert "'selector = initsel_ros.ros.node:main'" in setup


def test_the_packaged_params_file_matches_the_node_in_any_namespace():
    from initsel_ros.ros.params import load_params_file

    text = (ROOT / 'config' / 'selector.yaml').read_text()
    assert '\n/**/selector:\n' in text
    assert load_params_file(ROOT / 'config' / 'selector.yaml')['mode'] == 'once'
