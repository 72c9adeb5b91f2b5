"""Options shared by several ``initsel`` subcommands, defined once."""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from initsel_ros.names import Mode
from initsel_ros.output import OutputError, check_file_target

if TYPE_CHECKING:
    from initsel_ros.learn.real_baselines.orbslam3_runner import Orbslam3Setup
    from initsel_ros.selector import SelectorConfig

Options = TypeVar('Options')

#: The values of ``--scale-rule``: those of :class:`initsel_ros.learn.labels.ScaleRule` (not
#: imported: ``--help`` stays light; a test holds the two equal).
SCALE_RULES = ('median', 'first_two')


def add_models_option(
    parser: argparse.ArgumentParser,
    help_text: str = 'model file (default: the packaged config/models.json)',
) -> None:
    """``--models PATH``: one model file (default: the packaged config/models.json)."""
    parser.add_argument('--models', type=Path, default=None, metavar='PATH', help=help_text)


def add_params_file_option(parser: argparse.ArgumentParser) -> None:
    """``--params-file YAML``: the selector's settings from a node parameter file."""
    parser.add_argument(
        '--params-file',
        type=Path,
        default=None,
        metavar='YAML',
        help="the selector's settings from a ROS 2 parameter file of the node (as "
        'config/selector.yaml; its model_file and camera.* are not read: use --models and '
        "the sequence's own intrinsics; default: the node's defaults)",
    )


def node_settings(args: argparse.Namespace, command: str) -> Any:
    """The node's settings ``--params-file`` names (its defaults without one), validated
    as the node validates them: a ``ros.params.NodeSettings`` (imported here only, not at
    module level: the ROS boundary), or None after printing why to stderr (an unreadable
    file, or a value the node would refuse)."""
    import sys

    from initsel_ros.errors import ConfigError
    from initsel_ros.ros.params import NodeSettings, load_params_file

    try:
        if getattr(args, 'params_file', None) is None:
            return NodeSettings.from_values({})
        return NodeSettings.from_values(load_params_file(args.params_file))
    except ConfigError as exc:
        print(f'initsel {command}: error: {exc}', file=sys.stderr)
        return None


def selector_config(args: argparse.Namespace, command: str) -> SelectorConfig | None:
    """The selector's settings of :func:`node_settings` (``model_file`` and ``camera.*`` are
    the command's own business), or None after printing why to stderr."""
    settings = node_settings(args, command)
    return None if settings is None else settings.selector_config()


def add_inputs_argument(
    parser: argparse.ArgumentParser, name: str, metavar: str, help_text: str
) -> None:
    """Positional ``name``: one or more files or folders (paths)."""
    parser.add_argument(name, nargs='+', type=Path, metavar=metavar, help=help_text)


def add_work_option(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--work``: the folder for rendered sequences (None: the command uses a temporary one)."""
    parser.add_argument('--work', type=Path, default=None, help=help_text)


def add_scale_rule_option(
    parser: argparse.ArgumentParser | argparse._ArgumentGroup, default: str | None, help_text: str
) -> None:
    """``--scale-rule``: how E_R removes the monocular scale (``SCALE_RULES``)."""
    parser.add_argument('--scale-rule', choices=SCALE_RULES, default=default, help=help_text)


def output_file(value: str) -> Path:
    """argparse type: a file to write (refused at once when it names a folder, rather than
    after the work, when the write fails)."""
    try:
        return check_file_target(value)
    except OutputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def whole_number(low: int) -> Callable[[str], int]:
    """argparse type: an integer >= ``low``."""

    def parse(value: str) -> int:
        try:
            number = int(value)
        except ValueError:
            raise argparse.ArgumentTypeError(f'{value!r} is not an integer') from None
        if number < low:
            raise argparse.ArgumentTypeError(f'{value} is under {low}')
        return number

    parse.__name__ = f'integer >= {low}'  # (argparse names the type in its messages)
    return parse


def non_negative_seconds(value: str) -> float:
    """argparse type: a finite number of seconds >= 0."""
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{value!r} is not a number') from None
    if not math.isfinite(number) or number < 0:
        raise argparse.ArgumentTypeError(f'{value} is not a finite number >= 0')
    return number


def add_jobs_option(
    parser: argparse.ArgumentParser, default: int, help_text: str = 'worker processes'
) -> None:
    """``--jobs N``: worker processes (at least 1)."""
    parser.add_argument('--jobs', type=whole_number(1), default=default, help=help_text)


def add_out_dir_option(
    parser: argparse.ArgumentParser, help_text: str, *, required: bool = False
) -> None:
    """``--out-dir``: the folder for the command's Markdown and CSV tables (and figures)."""
    parser.add_argument('--out-dir', type=Path, default=None, required=required, help=help_text)


def add_source_option(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--source``: a recorded TUM folder or bag to use instead of a rendered sequence."""
    parser.add_argument('--source', type=Path, default=None, help=help_text)


def add_mode_option(parser: argparse.ArgumentParser, default: Mode | None, help_text: str) -> None:
    """``--mode``: what the selector does after an initialization (:class:`Mode`); None: no
    default (the command takes it from elsewhere)."""
    parser.add_argument(
        '--mode',
        choices=tuple(m.value for m in Mode),
        default=None if default is None else default.value,
        help=help_text,
    )


def add_rate_option(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--rate``: the playback speed factor of a published sequence (1: its own timing)."""
    parser.add_argument('--rate', type=float, default=1.0, help=help_text)


def add_kitti_sequence_option(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--sequence NN``: the KITTI odometry sequence, when a source is the odometry root."""
    parser.add_argument('--sequence', default=None, metavar='NN', help=help_text)


def add_bag_image_topic_option(parser: argparse.ArgumentParser) -> None:
    """``--bag-image-topic TOPIC``: which image topic of a bag is read."""
    parser.add_argument(
        '--bag-image-topic',
        default=None,
        metavar='TOPIC',
        help='bags: the image topic to read (Image or CompressedImage; default '
        '/camera/rgb/image_color, or <it>/compressed when absent)',
    )


def add_camera_option(parser: argparse.ArgumentParser) -> None:
    """``--camera NAME``: which camera of a EuRoC or KITTI folder is read."""
    parser.add_argument(
        '--camera',
        default=None,
        metavar='NAME',
        help='EuRoC: cam0 (default) or cam1; KITTI: 0-3, the image_N folder (default 0, or '
        'the first with images)',
    )


def add_intrinsics_option(parser: argparse.ArgumentParser) -> None:
    """``--intrinsics FILE``: the camera of TUM folders and bags, replacing their own."""
    parser.add_argument(
        '--intrinsics',
        type=Path,
        default=None,
        metavar='FILE',
        help='TUM folders and bags: YAML of the camera (fx, fy, cx, cy, width, height, '
        "distortion, as a TUM folder's intrinsics.yaml) replacing intrinsics.yaml or "
        'CameraInfo (without either they are the TUM fr3 camera)',
    )


def add_named_models_option(parser: argparse.ArgumentParser) -> None:
    """``--models [NAME=]PATH``, repeatable: several model files compared in one run."""
    parser.add_argument(
        '--models',
        action='append',
        default=None,
        metavar='[NAME=]PATH',
        help='model file, repeatable; a bare PATH is named by its file stem '
        '(default: shipped=the packaged config/models.json)',
    )


def add_orbslam3_options(parser: argparse.ArgumentParser) -> None:
    """``--orbslam3-venv``, ``--orbslam3-vocab`` and ``--orbslam3-timeout``: where the real
    ORB-SLAM3 baseline runs (scripts/setup_orbslam3.sh makes its venv)."""
    parser.add_argument(
        '--orbslam3-venv',
        type=Path,
        default=None,
        help='the ORB-SLAM3 venv (default $INITSEL_ORBSLAM3_VENV or ./.venv-orbslam3)',
    )
    parser.add_argument(
        '--orbslam3-vocab',
        type=Path,
        default=None,
        help='DBoW2 text vocabulary (default VENV/initsel_orbvoc.txt; see initsel orbvocab)',
    )
    parser.add_argument(
        '--orbslam3-timeout',
        type=float,
        default=300.0,
        metavar='S',
        help='seconds per batch before ORB-SLAM3 counts as failed (default 300)',
    )


def orbslam3_setup(args: argparse.Namespace) -> Orbslam3Setup:
    """The checked ORB-SLAM3 setup of :func:`add_orbslam3_options`' values.

    Raises:
        ConfigError: its venv, its orbslam3 package or the vocabulary is missing.
    """
    from initsel_ros.learn.real_baselines.orbslam3_runner import find_orbslam3

    return find_orbslam3(args.orbslam3_venv, args.orbslam3_vocab, args.orbslam3_timeout)


def model_path(value: Path | None) -> Path:
    """The ``--models`` file, or the packaged one."""
    from initsel_ros.models import default_model_path

    return Path(value) if value is not None else Path(default_model_path())


def named_model_paths(values: Sequence[str] | None) -> dict[str, Path]:
    """``--models [NAME=]PATH`` values as name -> path (a bare PATH is named by its stem);
    none: ``{'shipped': the packaged config/models.json}``.

    Raises:
        ValueError: two files with the same name.
    """
    if not values:
        return {'shipped': model_path(None)}
    out: dict[str, Path] = {}
    for value in values:
        name, sep, path = value.partition('=')
        if not sep:
            name, path = Path(value).stem, value
        if name in out:
            raise ValueError(f'model name {name!r} given twice (use NAME=PATH)')
        out[name] = Path(path)
    return out


def options_from(args: argparse.Namespace, cls: type[Options], **overrides: Any) -> Options:
    """The dataclass ``cls`` filled from the parsed options of the same names."""
    fields = {f.name: getattr(args, f.name) for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    return cls(**(fields | overrides))


__all__ = [
    'SCALE_RULES',
    'add_camera_option',
    'add_inputs_argument',
    'add_jobs_option',
    'add_kitti_sequence_option',
    'add_mode_option',
    'add_models_option',
    'add_named_models_option',
    'add_out_dir_option',
    'add_rate_option',
    'add_scale_rule_option',
    'add_source_option',
    'add_work_option',
    'model_path',
    'named_model_paths',
    'options_from',
]
