"""Session fixtures: rendered sequences (each rendered once, lazily, on first use).

Every fixture returns a Path: a TUM folder (``rgb/``, ``depth/``, ``rgb.txt``, ``depth.txt``,
``groundtruth.txt``, ``intrinsics.yaml``) or a bag. Treat them as read-only.
"""

from __future__ import annotations

from pathlib import Path

import pytest


def _render(factory: pytest.TempPathFactory, name: str, **kwargs: object) -> Path:
    from initsel_ros.synth import render

    out = factory.mktemp(name)
    return render(out, **kwargs).path  # type: ignore[arg-type]


@pytest.fixture(scope='session')
def near_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Default scene, real near trajectory frames 80-139 (2 s; 0.22 m baseline after 30 frames,
    0.39 m after 60); noise 1.5."""
    return _render(tmp_path_factory, 'near', trajectory='near', frames=60, start=80)


@pytest.fixture(scope='session')
def desk_start_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The README demo's first 64 frames (default scene, near trajectory from its start: 1.8 cm
    of baseline at frame 63)."""
    return _render(tmp_path_factory, 'desk_start', trajectory='near', frames=64)


@pytest.fixture(scope='session')
def desk_mirror_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The README seed map's desk batch 630 (near_test, seed 11, frames 630-665): an H whose
    two decompositions both hold on 15 verification frames, the fire path's choice the
    mirrored one."""
    return _render(
        tmp_path_factory, 'desk_mirror', trajectory='near', frames=36, start=630, seed=11
    )


@pytest.fixture(scope='session')
def low_texture_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Nearly untextured surfaces under a hand-held random motion (seed 912), 24 frames:
    most Shi-Tomasi detections lie on the straight edges between the surfaces."""
    return _render(
        tmp_path_factory,
        'low_texture',
        scene='low_texture',
        trajectory='random',
        frames=24,
        seed=912,
    )


@pytest.fixture(scope='session')
def far_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Default scene, the near motion (frames 80-139) at twice the distance."""
    return _render(tmp_path_factory, 'far', trajectory='far', frames=60, start=80)


@pytest.fixture(scope='session')
def rotation_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Pure pan and tilt about the optical centre (zero baseline), 60 frames."""
    return _render(tmp_path_factory, 'rotation', trajectory='rotation', frames=60)


@pytest.fixture(scope='session')
def static_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A camera that does not move, 30 frames (only the noise changes)."""
    return _render(tmp_path_factory, 'static', trajectory='static', frames=30)


@pytest.fixture(scope='session')
def floor_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Sheets on the floor only (every visible point on z = 0), near frames 80-139."""
    return _render(
        tmp_path_factory, 'floor', scene='floor', trajectory='near', frames=60, start=80
    )


@pytest.fixture(scope='session')
def wall_arc_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One textured wall (a single plane) seen from the arc trajectory, 60 frames."""
    return _render(
        tmp_path_factory, 'wall_arc', scene='wall', trajectory='arc', frames=60, start=15
    )


@pytest.fixture(scope='session')
def poster_arc_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A poster 1.2 m away seen from a sideways arc of 8 cm turning half-way back toward it
    (issue 20's hard case, the planar-arc family's poster of seed 8), 16 frames, no noise."""
    from initsel_ros.synth.trajectories import ArcPath

    arc = ArcPath(distance=1.2, extent=0.08, centring=0.5)
    return _render(
        tmp_path_factory, 'poster_arc', scene='wall', trajectory='arc', frames=16, seed=8, arc=arc
    )


@pytest.fixture(scope='session')
def near_pair_table(near_sequence: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``initsel dataset`` on ``near_sequence`` (batches of 30): a real labelled pair table."""
    from initsel_ros.cli import main

    out = tmp_path_factory.mktemp('pairs') / 'near.csv'
    assert (
        main(
            [
                'dataset',
                str(near_sequence),
                '--out',
                str(out),
                '--batch',
                '30',
                '--jobs',
                '1',
                '--quiet',
                '--no-orbslam',
            ]
        )
        == 0
    )
    return out


@pytest.fixture(scope='session')
def near_bag_ros1(near_sequence: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``near_sequence`` as a ROS 1 bag file."""
    from initsel_ros.datasets.bags import write_bag
    from initsel_ros.datasets.tum import TumSequence

    return write_bag(
        TumSequence(near_sequence), tmp_path_factory.mktemp('bag1') / 'near.bag', 'ros1'
    )


@pytest.fixture(scope='session')
def near_bag_ros2(near_sequence: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``near_sequence`` as a ROS 2 bag folder (sqlite3)."""
    from initsel_ros.datasets.bags import write_bag
    from initsel_ros.datasets.tum import TumSequence

    return write_bag(TumSequence(near_sequence), tmp_path_factory.mktemp('bag2') / 'near', 'ros2')


@pytest.fixture(scope='session')
def near_evaluation(near_pair_table: Path) -> tuple:
    """(table, shipped models, :func:`~initsel_ros.learn.evaluate.evaluate` report) on
    ``near_pair_table``."""
    from initsel_ros.learn.evaluate import evaluate
    from initsel_ros.learn.table import read_table
    from initsel_ros.models import ModelSet, default_model_path

    table = read_table(near_pair_table)
    models = ModelSet.load(default_model_path())
    return table, models, evaluate(table, models)


@pytest.fixture
def opened_sequences(monkeypatch: pytest.MonkeyPatch) -> list[tuple[object, dict]]:
    """Every ``datasets.open_sequence`` call of the test, as (path, reader options), in order
    (the sequences are still opened)."""
    import initsel_ros.datasets as datasets

    calls: list[tuple[object, dict]] = []
    open_sequence = datasets.open_sequence

    def recording(path: object, **options: object) -> object:
        calls.append((path, options))
        return open_sequence(path, **options)

    monkeypatch.setattr(datasets, 'open_sequence', recording)
    return calls
