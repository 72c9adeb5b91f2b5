"""The robustness measurements: ground truth of tracks, labelling of distorted sequences,
the comparison of model files and baselines, and the choice of the file to ship."""

from __future__ import annotations

import numpy as np
import pytest

from initsel_ros.datasets import open_sequence
from initsel_ros.learn import robustness as rb
from initsel_ros.learn.robustness import tracker
from initsel_ros.synth import Effects, render
from initsel_ros.tracking import KltTracker, TrackerConfig


@pytest.fixture(scope='module')
def distorted_near(tmp_path_factory):
    out = tmp_path_factory.mktemp('distorted') / 'near_distorted'
    return render(
        out,
        trajectory='near',
        start=80,
        frames=31,
        distortion=(-0.2, 0.06, 5e-4, -5e-4),
        effects=Effects(noise=1.0),
    ).path


def test_true_positions_follow_the_tracks_of_a_distorted_sequence(distorted_near):
    seq = open_sequence(distorted_near)
    tracker = KltTracker(TrackerConfig(photometric='none'))
    tracker.reset(seq.gray(0))
    for i in range(1, 31):
        tracks = tracker.track(seq.gray(i))
    truth, X, valid = rb.true_positions(
        tracks.ref, seq.depth(0), seq.intrinsics, seq.frames[0].pose, seq.frames[30].pose
    )
    err = np.linalg.norm(tracks.cur - truth, axis=1)[valid]
    assert valid.mean() > 0.95 and np.median(err) < 0.5
    assert np.median(np.linalg.norm(tracks.cur - tracks.ref, axis=1)) > 10  # it moved
    assert np.all(X[valid, 2] > 0.5)


def test_track_sequence_measures_seed_maps_against_the_true_pose(near_sequence):
    results, remaps = rb.track_sequence(
        tracker._Cached(open_sequence(near_sequence)), TrackerConfig()
    )
    assert remaps == 0  # no brightness change: the tracker never remaps
    summary = tracker._summary(results)
    assert summary['pairs'] > 10 and summary['et_median'] < 0.1
    assert summary['track_err_px'] < 0.5 and summary['depth_err_median'] < 0.05
    assert '| clean | gain_bias |' in rb.tracker_markdown(
        [
            {
                'condition': 'clean',
                'mode': 'gain_bias',
                **summary,
                'seconds_per_frame': 0.004,
                'remaps': 0.0,
            }
        ]
    )


def test_labels_of_a_distorted_sequence_use_undistorted_points(distorted_near):
    rows = rb.label_sequence(open_sequence(distorted_near))
    assert len(rows) == 29  # one batch of 30 frames
    wide = [r for r in rows if r['gt_baseline_m'] > 0.15]
    assert wide and np.median([r['E_et'] for r in wide]) < 0.1
    assert np.mean([r['E_label'] for r in wide]) > 0.8
    # one labelling: exactly the rows `initsel dataset` makes of the same batch
    from initsel_ros.learn.pairs import DatasetConfig, label_sequence_batch

    table = label_sequence_batch(
        open_sequence(distorted_near), 0, range(30), DatasetConfig(batch=30, jobs=1)
    )
    np.testing.assert_array_equal([r['E_et'] for r in table], [r['E_et'] for r in rows])


# ----------------------------------------------------------------------------- comparison
def _row(system, effect='noise', level='default', p=0.9, r=0.6, pan=0.05, kind='model', **kw):
    """A hand-made comparison row: precision p and recall r for every column."""
    row = {'effect': effect, 'level': level, 'system': system, 'kind': kind, 'pairs': 100}
    for m in rb.COLUMNS:
        row[f'{m}_precision'], row[f'{m}_recall'] = kw.get(f'{m}_p', p), kw.get(f'{m}_r', r)
    row.update(first_yes_good=0.7, false_yes_rotation=0.1, false_yes_pan=pan)
    return row


def _rows(candidate_clean_p, candidate_effect_r=0.9, candidate='mix'):
    """Reference 'shipped' and one candidate: clean rows and two effect rows each."""
    rows = [_row('shipped', 'none', 'clean', p=1.0), _row(candidate, 'none', 'clean')]
    rows[1].update({f'{m}_precision': candidate_clean_p for m in rb.COLUMNS})
    for level in ('default', 'strong'):
        rows += [_row('shipped', level=level), _row(candidate, level=level, r=candidate_effect_r)]
    rows.append(_row('ORB-SLAM2', level='default', p=1.0, r=1.0, kind='baseline', pan=0.0))
    return rows


def test_f1_score_is_nan_safe_and_zero_for_a_silent_rule():
    assert rb.f1_score(0.5, 0.5) == pytest.approx(0.5)
    assert rb.f1_score(np.nan, 0.0) == 0.0 and rb.f1_score(0.0, np.nan) == 0.0
    assert np.isnan(rb.f1_score(0.8, np.nan))


def test_choice_rejects_a_candidate_losing_more_than_the_clean_allowance():
    name, why = rb.choose_model(_rows(candidate_clean_p=0.94))  # 0.06 below the reference
    assert name == 'shipped'
    assert 'not eligible' in why and 'Chosen: `shipped`' in why


def test_choice_takes_a_better_candidate_within_the_clean_allowance():
    name, why = rb.choose_model(_rows(candidate_clean_p=0.95))  # exactly 0.05 below
    assert name == 'mix' and 'Chosen: `mix`' in why
    assert rb.choose_model(_rows(candidate_clean_p=0.97), max_clean_loss=0.01)[0] == 'shipped'
    # a worse candidate is eligible but does not win; baselines never compete
    assert rb.choose_model(_rows(0.99, candidate_effect_r=0.3))[0] == 'shipped'


def test_choice_is_not_won_by_never_firing_or_by_firing_on_the_pan():
    silent = _rows(candidate_clean_p=1.0, candidate='silent')
    for r in silent:
        if r['system'] == 'silent' and r['level'] != 'clean':
            r.update({f'{m}_precision': np.nan for m in rb.COLUMNS})  # nothing predicted
            r.update({f'{m}_recall': 0.0 for m in rb.COLUMNS}, false_yes_pan=0.0)
    assert rb.choose_model(silent)[0] == 'shipped'
    eager = _rows(candidate_clean_p=1.0, candidate='eager')
    for r in eager:
        if r['system'] == 'eager' and r['level'] != 'clean':
            r['false_yes_pan'] = 0.9  # higher recall, but says 'yes' on pure rotation
    assert rb.choose_model(eager)[0] == 'shipped'
    with pytest.raises(ValueError):
        rb.choose_model(eager, reference='nope')


def test_markdown_and_csv_of_the_comparison(tmp_path):
    import csv

    rows = _rows(candidate_clean_p=0.95)
    rows[-1].update(E_precision=np.nan, E_recall=np.nan, R_precision=np.nan, R_recall=np.nan)
    text = rb.comparison_markdown(rows, rb.choose_model(rows)[1])
    assert '| effect | strength | system |' in text
    assert '| noise | default | ORB-SLAM2 | 100 | 1.00 / 1.00 | - | 1.00 / 1.00 | - |' in text
    assert '| none | clean | shipped |' in text and 'Chosen: `mix`' in text
    path = rb.write_comparison_csv(rows, tmp_path / 'c.csv')
    with path.open() as fh:
        back = list(csv.DictReader(fh))
    assert len(back) == len(rows) and tuple(back[0]) == rb.CSV_COLUMNS
    assert float(back[0]['F_f1']) == pytest.approx(rb.f1_score(1.0, 0.6))
    assert back[-1]['kind'] == 'baseline' and back[-1]['E_f1'] == ''


def test_plots_of_the_comparison_are_written(tmp_path):
    pytest.importorskip('matplotlib')
    rows = _rows(candidate_clean_p=0.95)
    rows.append(_row('shipped', effect='jpeg', level='default'))
    paths = rb.plot_comparison(rows, tmp_path / 'plots')
    names = sorted(p.name for p in paths)
    assert names == ['false_yes_pan.png', 'precision_jpeg.png', 'precision_noise.png']
    assert all(p.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' for p in paths)


def test_compare_models_scores_two_files_and_the_baselines_on_the_same_pairs(tmp_path):
    from initsel_ros.models import default_model_path

    models = {'shipped': default_model_path(), 'copy': default_model_path()}
    rows = rb.compare_models(tmp_path, models, ['noise'], ('clean',), frames=(31, 31))
    assert [r['system'] for r in rows] == ['shipped', 'copy', *rb.BASELINES]
    assert len({r['pairs'] for r in rows}) == 1 and rows[0]['pairs'] > 40
    for r in rows:
        has = rb.MODEL_ROWS if r['kind'] == 'model' else rb.BASELINES[r['system']]
        for m in rb.COLUMNS:
            # recall wherever the system has the method; precision too unless it never said
            # yes (e.g. ORB-SLAM3's H on these pairs): then it is undefined, NaN
            assert np.isfinite(r[f'{m}_recall']) == (m in has), (r['system'], m)
            if np.isfinite(r[f'{m}_precision']):
                assert m in has, (r['system'], m)
        assert np.isfinite(r['false_yes_pan']) and np.isfinite(r['false_yes_rotation'])
    a, b = rows[:2]
    same = [k for k in a if k != 'system']
    assert [str(a[k]) for k in same] == [str(b[k]) for k in same]  # NaN-tolerant equality
    name, _ = rb.choose_model(rows)
    assert name == 'shipped'  # no effect rows: the reference keeps its place


def test_a_model_silent_on_clean_pairs_loses_recall_not_precision():
    # H that never fires on the clean pairs: its precision is undefined, so it does not
    # count against the clean allowance; its recall of 0 already costs it score.
    rows = _rows(candidate_clean_p=1.0)
    clean = next(r for r in rows if r['system'] == 'mix' and r['level'] == 'clean')
    clean.update(H_precision=np.nan, H_recall=0.0)
    name, why = rb.choose_model(rows)
    assert name == 'mix' and 'not eligible' not in why
    assert rb.f1_score(clean['H_precision'], clean['H_recall']) == 0.0
