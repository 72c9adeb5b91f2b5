"""The ROS boundary is a folder: no module outside ``initsel_ros/ros/`` imports ROS.

Every module of the package outside ``ros/`` is found by walking the package (none is
hand-picked), parsed with ast and checked for imports of rclpy or a message package anywhere
in the file (functions included); imports of ``initsel_ros.ros`` are allowed only inside
functions (the lazy hand-offs to the live tools). Then all of them are imported in a fresh
interpreter where rclpy and the message packages cannot be imported.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest
from boundary_fixtures import is_ros_package, ros_blocker, without_ros_environment

PACKAGE = Path(__file__).resolve().parent.parent / 'initsel_ros'
ROS_DIR = PACKAGE / 'ros'


def core_files() -> list[Path]:
    """Every Python file of the package outside ``initsel_ros/ros/``."""
    return sorted(p for p in PACKAGE.rglob('*.py') if ROS_DIR not in p.parents)


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def _imports(tree: ast.AST, module: str, is_package: bool) -> list[tuple[ast.stmt, str, bool]]:
    """(node, absolute module imported, inside a function) for every import in ``tree``."""
    found = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(
                child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)
            )
            if isinstance(child, ast.Import):
                found.extend((child, alias.name, in_function) for alias in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:  # relative: resolve against this module's package
                    base = module.split('.')
                    base = base[: len(base) - child.level + (1 if is_package else 0)]
                    target = '.'.join(base + ([child.module] if child.module else []))
                else:
                    target = child.module or ''
                found.append((child, target, in_function))
                if target == 'initsel_ros':  # from initsel_ros import ros
                    found.extend(
                        (child, f'{target}.{alias.name}', in_function) for alias in child.names
                    )
            visit(child, inner)

    visit(tree, False)
    return found


def violations(path: Path) -> list[str]:
    """The boundary violations of one file, as 'file:line: what' strings."""
    return source_violations(
        path.read_text(),
        module_name(path),
        path.name == '__init__.py',
        str(path.relative_to(PACKAGE.parent)),
    )


def source_violations(source: str, module: str, is_package: bool, where: str) -> list[str]:
    """The boundary violations of the source of ``module``."""
    tree = ast.parse(source, filename=where)
    out = []
    for node, target, in_function in _imports(tree, module, is_package):
        if is_ros_package(target):
            out.append(f'{where}:{node.lineno}: imports {target}')
        elif (
            target == 'initsel_ros.ros' or target.startswith('initsel_ros.ros.')
        ) and not in_function:
            out.append(f'{where}:{node.lineno}: imports {target} at module level')
    return sorted(set(out))


def test_the_walk_finds_every_module_outside_ros():
    files = core_files()
    names = {module_name(p) for p in files}
    assert {
        'initsel_ros',
        'initsel_ros.selector',
        'initsel_ros.status',
        'initsel_ros.demo',
        'initsel_ros.bench',
        'initsel_ros.benchmarks.live',
        'initsel_ros.learn.evaluate',
        'initsel_ros.datasets.bags',
        'initsel_ros.synth.render',
    } <= names
    assert not any(n.startswith('initsel_ros.ros') for n in names)
    assert len(files) > 40


def test_no_module_outside_ros_imports_rclpy_or_a_message_package():
    problems = [v for path in core_files() for v in violations(path)]
    assert problems == [], '\n'.join(problems)


@pytest.mark.parametrize(
    ('source', 'expected'),
    [
        ('import rclpy', ['imports rclpy']),
        ('def f():\n    from sensor_msgs.msg import Image', ['imports sensor_msgs.msg']),
        ('from custom_msgs.msg import Thing', ['imports custom_msgs.msg']),
        ('from initsel_ros.ros import conversions', ['imports initsel_ros.ros at module level']),
        ('from .ros.node import SelectorNode', ['imports initsel_ros.ros.node at module level']),
        ('from . import ros', ['imports initsel_ros.ros at module level']),
        ('def f():\n    from initsel_ros.ros.demo_live import run_live', []),
        ('import rosbags.highlevel\nimport numpy', []),
    ],
)
def test_the_scan_catches_ros_imports_anywhere(source, expected):
    found = {
        v.split(': ', 1)[1]
        for v in source_violations(source, 'initsel_ros.probe', False, 'probe.py')
    }
    assert set(expected) <= found
    assert bool(found) == bool(expected)


IMPORT_ALL = """
import importlib, json, traceback
report = {{'ok': [], 'optional': {{}}, 'failed': {{}}}}
for name in {modules!r}:
    try:
        importlib.import_module(name)
        report['ok'].append(name)
    except ImportError as exc:
        if 'blocked for this test' in str(exc) or 'blocked for this test' in repr(exc.__cause__):
            report['failed'][name] = traceback.format_exc()
        else:  # an optional dependency (an extra) that is not installed here
            report['optional'][name] = str(exc)
    except Exception:
        report['failed'][name] = traceback.format_exc()
print(json.dumps(report))
"""


def test_every_module_outside_ros_imports_with_ros_blocked():
    modules = sorted({module_name(p) for p in core_files()})
    code = ros_blocker() + IMPORT_ALL.format(modules=modules)
    out = subprocess.run(
        [sys.executable, '-c', code],
        capture_output=True,
        text=True,
        timeout=300,
        env=without_ros_environment(),
    )
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report['failed'] == {}, '\n'.join(report['failed'].values())
    assert 'initsel_ros.status' in report['ok'] and 'initsel_ros.demo' in report['ok']
    assert len(report['ok']) + len(report['optional']) == len(modules)
