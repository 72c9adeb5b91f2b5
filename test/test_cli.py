"""Tests for initsel_ros.cli: the subcommand table, light --help, errors, default folders."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from initsel_ros.cli import SUBCOMMANDS, SubcommandImportError, build_parser, main
from initsel_ros.cli.options import named_model_paths

#: Modules that ``--help`` must not import: OpenCV, the learning stack, ROS.
HEAVY = ('cv2', 'sklearn', 'rclpy', 'scipy', 'matplotlib')

_PROBE = textwrap.dedent("""
    import json, sys
    from initsel_ros.cli import main
    try:
        code = main(sys.argv[1:])
    except SystemExit as exc:
        code = exc.code
    sys.stdout.flush()
    print('\\n' + json.dumps({'code': code, 'modules': sorted(sys.modules)}))
""")


def _clean_env() -> dict[str, str]:
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ('_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'LD_LIBRARY_PATH')
    }
    return env


def _help_modules(*argv: str) -> tuple[int, list[str]]:
    out = subprocess.run(
        [sys.executable, '-c', _PROBE, *argv, '--help'],
        env=_clean_env(),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    record = json.loads(out.stdout.strip().splitlines()[-1])
    return record['code'], record['modules']


def _heavy(modules: list[str]) -> list[str]:
    return [m for m in modules if m.split('.')[0] in HEAVY]


@pytest.mark.parametrize('command', [None, *SUBCOMMANDS])
def test_help_imports_no_opencv_learning_stack_or_ros(command):
    code, modules = _help_modules(*([command] if command else []))
    assert code == 0
    assert _heavy(modules) == []


def test_console_script_help_runs_in_a_subprocess():
    script = Path(sys.executable).with_name('initsel')
    if not script.exists():
        pytest.skip('console script not installed next to this Python')
    out = subprocess.run(
        [str(script), '--help'],
        env=_clean_env(),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    for name in SUBCOMMANDS:
        assert name in out.stdout


def test_every_subcommand_module_exposes_add_arguments_and_run():
    import importlib

    for name, (module_name, _help) in SUBCOMMANDS.items():
        assert module_name == f'initsel_ros.cli.{name}'
        module = importlib.import_module(module_name)
        assert callable(module.add_arguments) and callable(module.run)
    parser = build_parser()
    for name in SUBCOMMANDS:
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([name, '--help'])
        assert exc.value.code == 0


def test_missing_subcommand_module_is_an_error(monkeypatch, capsys):
    monkeypatch.setitem(SUBCOMMANDS, 'broken', ('initsel_ros.cli.no_such_module', 'broken'))
    with pytest.raises(SubcommandImportError, match=r"'broken'.*no_such_module"):
        build_parser()
    assert main(['--help']) == 1
    assert 'broken' in capsys.readouterr().err


def test_subcommand_module_with_a_failing_import_is_an_error(tmp_path, monkeypatch, capsys):
    (tmp_path / 'initsel_test_broken_cli.py').write_text(
        'import initsel_no_such_dependency  # noqa: F401\n'
        'def add_arguments(parser): pass\n'
        'def run(args): return 0\n'
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(SUBCOMMANDS, 'broken', ('initsel_test_broken_cli', 'broken'))
    assert main(['synth', '--help']) == 1
    err = capsys.readouterr().err
    assert 'initsel_no_such_dependency' in err and err.count('\n') == 1


def test_readme_pictures_default_folder_is_relative_to_the_working_directory(
    tmp_path,
    monkeypatch,
):
    import initsel_ros.pictures as pictures

    assert not pictures.README_IMAGES.is_absolute()
    seen = {}

    def fake_make(out, work, models, frames):
        seen['out'] = Path(out).resolve()
        return []

    monkeypatch.setattr(pictures, 'make_readme_pictures', fake_make)
    monkeypatch.chdir(tmp_path)
    assert main(['pictures']) == 0
    assert seen['out'] == (tmp_path / 'docs' / 'images').resolve()
    assert Path(pictures.__file__).resolve().parent.parent not in seen['out'].parents


def test_models_arguments_take_names_or_file_stems():
    got = named_model_paths(['shipped=config/models.json', '/tmp/effects_mix.json'])
    assert got == {
        'shipped': Path('config/models.json'),
        'effects_mix': Path('/tmp/effects_mix.json'),
    }
    assert list(named_model_paths(None)) == ['shipped']
    with pytest.raises(ValueError):
        named_model_paths(['a=x.json', 'a=y.json'])


def test_argparse_is_imported_only_by_the_command_line_modules():
    import ast

    package = Path(__file__).resolve().parent.parent / 'initsel_ros'
    allowed = {package / 'ros' / 'node.py'}  # the node's own ``main``
    importers = set()
    for path in package.rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or '']
                if isinstance(node, ast.ImportFrom)
                else []
            )
            if any(n.split('.')[0] == 'argparse' for n in names):
                importers.add(path)
    outside = sorted(
        str(p.relative_to(package)) for p in importers - allowed if p.parent.name != 'cli'
    )
    assert outside == []


def test_scale_rule_choices_are_the_label_rules():
    from initsel_ros.cli.options import SCALE_RULES
    from initsel_ros.learn.labels import ScaleRule

    assert set(SCALE_RULES) == {r.value for r in ScaleRule}


def test_train_options_name_every_feature_the_models_can_read():
    """``initsel train``'s choices are spelled out (its --help loads no OpenCV): they must
    stay the features module's names, or a new feature cannot be asked for."""
    from initsel_ros.cli.train import EXTRA, PAPER
    from initsel_ros.features import EXTRA_FEATURE_NAMES, FEATURE_NAMES

    assert PAPER == FEATURE_NAMES
    assert EXTRA == EXTRA_FEATURE_NAMES


def test_train_options_name_every_label_rule():
    from initsel_ros.cli import train
    from initsel_ros.learn import labels

    assert train.METHOD_LABELS == labels.METHOD_LABELS
    assert train.ROTATION_LABELS == labels.ROTATION_LABELS
