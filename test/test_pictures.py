"""Tests for initsel_ros.pictures: overlay videos, PNG frames and the probability figure."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from model_fixtures import constant_models

from initsel_ros.camera import Intrinsics
from initsel_ros.datasets import Frame, Sequence, open_sequence
from initsel_ros.pictures import (
    groundtruth_baselines,
    iter_overlays,
    make_readme_pictures,
    plot_probabilities,
    write_overlay_video,
    write_png,
)
from initsel_ros.policy import Reason
from initsel_ros.selector import SelectorConfig


def main(argv: list[str]) -> int:
    """``initsel pictures ARGV`` (the command that ``python -m initsel_ros.pictures`` was)."""
    from initsel_ros.cli import main as initsel

    return initsel(['pictures', *argv])


STEP_M = 0.01  # camera moves this far along x per frame
STEP_PX = 2.0  # and the image shifts this far


class ShiftSequence(Sequence):
    """In-memory frames: one texture shifted a little more each frame, with poses."""

    def __init__(self, n: int, seed: int = 3) -> None:
        rng = np.random.default_rng(seed)
        coarse = rng.uniform(0, 255, (60, 80, 3)).astype(np.float32)
        self._texture = np.clip(
            cv2.resize(coarse, (640, 480), interpolation=cv2.INTER_CUBIC), 0, 255
        ).astype(np.uint8)
        frames = []
        for i in range(n):
            pose = np.eye(4)
            pose[0, 3] = STEP_M * i
            frames.append(Frame(i, 100.0 + i / 30.0, pose))
        super().__init__('shift', Intrinsics.tum_fr3(), frames)

    def _load_image(self, i: int) -> np.ndarray:
        M = np.float32([[1, 0, -STEP_PX * i], [0, 1, 0]])
        return cv2.warpAffine(self._texture, M, (640, 480), borderMode=cv2.BORDER_REFLECT)


@pytest.fixture(scope='module')
def shift_sequence() -> ShiftSequence:
    return ShiftSequence(12)


def test_overlay_video_is_readable_frame_by_frame(shift_sequence, tmp_path):
    out = tmp_path / 'overlay.mp4'
    run = write_overlay_video(shift_sequence, constant_models(), out)
    assert run.frames_written == len(shift_sequence) and out.stat().st_size > 1000
    cap = cv2.VideoCapture(str(out))
    try:
        frames = []
        while True:
            ok, img = cap.read()
            if not ok:
                break
            frames.append(img)
    finally:
        cap.release()
    assert len(frames) == len(shift_sequence)
    assert frames[0].shape == (480, 640, 3)
    # the overlay, not the raw frame: the darkened panel in the top-left corner
    raw = shift_sequence.image(5).astype(float)
    assert frames[5][:60, :200].mean() < 0.6 * raw[:60, :200].mean()


def test_overlay_frames_as_png_folder_named_by_index(shift_sequence, tmp_path):
    run = write_overlay_video(
        shift_sequence, constant_models(), tmp_path / 'frames', start=2, stop=6
    )
    names = sorted(p.name for p in (tmp_path / 'frames').glob('*.png'))
    assert names == [f'frame_{i:06d}.png' for i in range(2, 6)]
    assert list(run.indices) == [2, 3, 4, 5]
    assert cv2.imread(str(tmp_path / 'frames' / names[0])).shape == (480, 640, 3)


def test_groundtruth_baseline_is_the_distance_to_the_reference(shift_sequence, tmp_path):
    config = SelectorConfig(max_frames_since_reference=5, min_seconds_since_reference=0.0)
    run = write_overlay_video(shift_sequence, constant_models(), tmp_path / 'o.mp4', config)
    base = groundtruth_baselines(shift_sequence, run.results, run.indices)
    # frame 0 and frame 5 become references (renewed after 5 frames)
    expected = STEP_M * np.array([0, 1, 2, 3, 4, 5, 1, 2, 3, 4, 5, 1])
    np.testing.assert_allclose(base, expected, atol=1e-9)


def test_small_png_is_posterized_until_it_fits(tmp_path):
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
    full = write_png(tmp_path / 'full.png', noise)
    small = write_png(tmp_path / 'small.png', noise, max_bytes=300_000)
    assert full.stat().st_size > 300_000 >= small.stat().st_size
    assert cv2.imread(str(small)) is not None


def test_probability_figure_is_written(shift_sequence, tmp_path):
    pytest.importorskip('matplotlib', reason='the figure needs the optional matplotlib (plot)')
    models = constant_models(E=0.9, F=0.8, R=0.9)  # R vetoes E and F on every frame
    run = write_overlay_video(shift_sequence, models, tmp_path / 'o.mp4')
    assert any(r.decision.reason is Reason.ROTATION for r in run.results)
    base = groundtruth_baselines(shift_sequence, run.results, run.indices)
    out = plot_probabilities(
        run.results, base, tmp_path / 'fig' / 'p.png', run.thresholds, run.indices, title='test'
    )
    img = cv2.imread(str(out))
    assert img is not None and img.shape[0] >= 300 and img.shape[1] >= 600
    assert img.std() > 10  # not blank


def test_probability_figure_without_ground_truth_or_results(tmp_path):
    pytest.importorskip('matplotlib', reason='the figure needs the optional matplotlib (plot)')
    out = plot_probabilities([], None, tmp_path / 'empty.png')
    assert cv2.imread(str(out)) is not None


def test_command_draws_a_rendered_rotation_sequence(rotation_sequence, tmp_path):
    pytest.importorskip('matplotlib', reason='the figure needs the optional matplotlib (plot)')
    model_file = tmp_path / 'models.json'
    constant_models(E=0.9, R=0.9).save(model_file)
    video, figure = tmp_path / 'rot.mp4', tmp_path / 'rot.png'
    code = main(
        [
            '--source',
            str(rotation_sequence),
            '--video',
            str(video),
            '--plot',
            str(figure),
            '--models',
            str(model_file),
            '--frames',
            '15',
        ]
    )
    assert code == 0
    cap = cv2.VideoCapture(str(video))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 15
    cap.release()
    assert cv2.imread(str(figure)) is not None


def test_command_without_an_output_is_one_error_line(rotation_sequence, tmp_path, capsys):
    model_file = tmp_path / 'models.json'
    constant_models().save(model_file)
    assert main(['--source', str(rotation_sequence), '--models', str(model_file)]) == 1
    assert 'needs --video' in capsys.readouterr().err


def test_rotation_sequence_has_no_baseline(rotation_sequence):
    seq = open_sequence(rotation_sequence)
    run = list(iter_overlays(seq, constant_models(), stop=10))
    base = groundtruth_baselines(seq, [r for _, r, _, _ in run], [i for i, _, _, _ in run])
    assert np.nanmax(base) < 1e-6


def test_readme_pictures_are_small_pngs(tmp_path):
    pytest.importorskip('matplotlib', reason='the figure needs the optional matplotlib (plot)')
    paths = make_readme_pictures(
        tmp_path / 'images',
        tmp_path / 'work',
        constant_models(E=0.9, R=0.2),
        frames=12,
        rotation_frames=6,
    )
    names = {p.name for p in paths}
    assert {'rotation_veto.png', 'probabilities.png'} <= names
    for p in paths:
        assert 0 < p.stat().st_size < 300_000 and cv2.imread(str(p)) is not None
