"""Leave-one-family-out generalization (issue 21): families, folds, scores, the CLI."""

from __future__ import annotations

import numpy as np
import pytest
from table_fixtures import synthetic_table

from initsel_ros.cli import main
from initsel_ros.errors import ConfigError, DatasetError
from initsel_ros.learn.generalize import (
    CEILING_RECALL,
    FIRE_H,
    Families,
    final_test,
    fire_path_h,
    generalization_markdown,
    leave_family_out,
    score_family,
)
from initsel_ros.learn.table import PairTable, input_columns, write_table
from initsel_ros.learn.train import TrainConfig, train_models

FAMILIES_YAML = """\
families:
  fx: ['fx_*']
  desk: ['far_*', desk]
  floor: [floor_far]
  walls: ['wall_*']
reserved: walls
"""


def _table_of(sequences: list[str], n: int = 240, seed: int = 0) -> PairTable:
    """The synthetic table with its rows spread over ``sequences`` (6 batches each)."""
    table = synthetic_table(n=n, seed=seed)
    cols = dict(table.columns)
    cols['sequence'] = np.array([sequences[i % len(sequences)] for i in range(n)], dtype=object)
    return PairTable(cols)


def test_families_file_assigns_every_sequence_by_its_first_matching_pattern(tmp_path):
    path = tmp_path / 'families.yaml'
    path.write_text(FAMILIES_YAML)
    families = Families.load(path)
    assert families.reserved == 'walls'
    got = families.assign(['fx_far_s101', 'far_s1', 'desk', 'floor_far', 'wall_arc_s0'])
    assert list(got) == ['fx', 'desk', 'desk', 'floor', 'walls']  # fx_far: fx, listed first
    with pytest.raises(ConfigError, match='in no family: random_s5'):
        families.assign(['far_s1', 'random_s5'])


@pytest.mark.parametrize(
    'text, message',
    [
        ('families: {}\n', 'at least one family'),
        ('families: {a: [x]}\nreserved: b\n', 'reserved family'),
        ('families: {a: 3}\n', 'list of name patterns'),
        ('[1, 2]\n', '"families" mapping'),
        ('families: [\n', 'cannot read'),
        ('families: {a: [x]}\nreserve: a\n', "unknown keys \\['reserve'\\]"),
        ('families: {a: [x]}\nreserved: [a]\n', 'must name one family'),
    ],
)
def test_a_bad_families_file_is_a_clear_error(tmp_path, text, message):
    path = tmp_path / 'families.yaml'
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        Families.load(path)


def test_each_family_is_scored_by_models_that_never_saw_it_nor_the_reserved_one(monkeypatch):
    # 480 pairs: with 240, trees on the table's ~40 noise columns overfit enough that E, after
    # R's veto, may never say yes on one held-out family of 60 (seen when a column was added)
    table = _table_of(['fx_a', 'far_s1', 'floor_far', 'wall_x'], n=480)
    families = Families({'fx': ('fx_*',), 'desk': ('far_*',), 'floor': ('floor_*',),
                         'walls': ('wall_*',)}, reserved='walls')  # fmt: skip
    seen: list[set[str]] = []
    import initsel_ros.learn.generalize as generalize

    def spy(train, config):
        seen.append(set(np.asarray(train['sequence']).astype(str)))
        return train_models(train, config)

    monkeypatch.setattr(generalize, 'train_models', spy)
    config = TrainConfig(folds=3)
    scores = leave_family_out(table, families, config, min_positives=5)
    assert [s.family for s in scores[::4]] == ['fx', 'desk', 'floor']  # the reserved: no fold
    assert seen == [{'far_s1', 'floor_far'}, {'fx_a', 'floor_far'}, {'fx_a', 'far_s1'}]
    assert {s.model for s in scores} == {'E', 'F', 'H', 'R'}
    assert all(s.pairs == 120 and s.scored for s in scores)
    # the labels follow one feature in every family: held out, each is still scored better
    # than chance (about 0.5 here), on the labels and at thresholds fitted without it
    assert all(s.precision > 0.6 for s in scores)
    assert np.mean([s.precision for s in scores if s.model == 'E']) > 0.8
    final = final_test(table, families, config, min_positives=5)
    assert seen[-1] == {'fx_a', 'far_s1', 'floor_far'} and {s.family for s in final} == {'walls'}


def test_a_family_without_pairs_is_logged_and_a_missing_reserved_one_is_an_error(caplog):
    table = _table_of(['fx_a', 'far_s1'], n=120)
    families = Families({'fx': ('fx_*',), 'desk': ('far_*',), 'floor': ('floor_*',),
                         'walls': ('wall_*',)}, reserved='walls')  # fmt: skip
    scores = leave_family_out(table, families, TrainConfig(folds=3), min_positives=5)
    assert {s.family for s in scores} == {'fx', 'desk'}
    assert 'families with no pairs in these tables, not scored: floor' in caplog.text
    assert f'no fire-path outcome (initsel dataset --fire-path): no row of {FIRE_H}' in caplog.text
    with pytest.raises(DatasetError, match="no pairs of the reserved family 'walls'"):
        final_test(table, families, TrainConfig(folds=3))
    with pytest.raises(DatasetError, match='needs two families'):
        leave_family_out(table.select(np.arange(0, 120, 2)), families, TrainConfig(folds=3))


def test_held_out_pairs_are_scored_on_the_labels_the_models_learnt():
    # relabelling by the training options happens before the split: with an E_t threshold
    # no pair reaches, no held-out pair is an E positive either
    from initsel_ros.learn.labels import LabelConfig

    table = _table_of(['fx_a', 'far_s1', 'floor_far'], n=180)
    cols = dict(table.columns)
    for m in ('F', 'E', 'H'):
        cols[f'{m}_et'] = np.abs(cols[f'{m}_et']) + 5.0
    table = PairTable(cols)
    families = Families({'fx': ('fx_*',), 'desk': ('far_*',), 'floor': ('floor_*',)})
    config = TrainConfig(folds=3, labels=LabelConfig(et_max=0.1), allow_degenerate=True)
    scores = leave_family_out(table, families, config, min_positives=5)
    assert {s.positives for s in scores if s.model in ('E', 'F')} == {0}


def test_scores_are_those_of_the_policy_after_the_r_veto():
    table = _table_of(['far_s1'])
    models = train_models(table, TrainConfig(folds=3)).models
    scores = {s.model: s for s in score_family(models, table, 'desk', min_positives=1000)}
    X = table.matrix(input_columns(models.input_names, models.scaling))
    probs = models.predict_proba_batch(X)
    fired = {m: probs[m] >= models.thresholds[m] for m in probs}
    y = np.asarray(table['E_label']).astype(bool)
    pred = fired['E'] & ~fired['R']
    assert scores['E'].precision == pytest.approx((y & pred).sum() / max(pred.sum(), 1))
    assert scores['E'].recall == pytest.approx((y & pred).sum() / y.sum())
    assert not any(s.scored for s in scores.values())  # 1000 positives needed


def test_the_ceiling_is_the_best_precision_at_half_recall_of_a_threshold_on_the_family():
    from dataclasses import replace

    table = _table_of(['far_s1'])
    models = train_models(table, TrainConfig(folds=3)).models
    X = table.matrix(input_columns(models.input_names, models.scaling))
    probs = models.predict_proba_batch(X)
    # R's threshold at its median probability: it vetoes half the pairs
    r = replace(models.models['R'], threshold=float(np.median(probs['R'])))
    models = replace(models, models={**models.models, 'R': r})
    scores = {s.model: s for s in score_family(models, table, 'desk', min_positives=1)}
    vetoed = probs['R'] >= models.thresholds['R']
    assert 0.3 < vetoed.mean() < 0.7
    for m in 'EFHR':
        y = np.asarray(table[f'{m}_label']).astype(bool)
        allowed = np.ones(len(y), bool) if m == 'R' else ~vetoed
        best = np.nan
        for t in np.unique(probs[m]):  # every threshold, by brute force
            pred = (probs[m] >= t) & allowed
            if y.sum() and (pred & y).sum() >= CEILING_RECALL[m] * y.sum():
                best = np.nanmax([best, (pred & y).sum() / pred.sum()])
        assert scores[m].ceiling == pytest.approx(best, nan_ok=True)
        if np.isfinite(scores[m].precision) and scores[m].recall >= CEILING_RECALL[m]:
            assert scores[m].ceiling >= scores[m].precision - 1e-12  # the chosen one is a t
    text = generalization_markdown(list(scores.values()), min_positives=1)
    assert 'The ceiling: the highest precision' in text and '| worst scored family |' in text
    # by hand: a vetoed pair is never a yes, and its positives still count in the recall
    from initsel_ros.learn.generalize import _ceiling

    y = np.array([1, 1, 0, 1, 0, 0], bool)
    s = np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4])
    assert _ceiling(y, s, np.ones(6, bool), 0.5) == 1.0  # t = 0.8: 2 of 3 positives
    assert _ceiling(y, s, np.ones(6, bool), 0.9) == 0.75  # t = 0.6: all 3, and 1 negative
    assert _ceiling(y, s, np.arange(6) != 0, 0.5) == pytest.approx(2 / 3)  # t = 0.6
    assert np.isnan(_ceiling(y, s, np.arange(6) > 1, 0.5))  # 1 of 3 positives at most


def test_the_table_names_the_worst_family_and_leaves_out_the_unscored_ones():
    from initsel_ros.learn.generalize import FamilyScore

    scores = []
    for family, p, scored in (('a', 0.9, True), ('b', 0.6, True), ('c', 0.1, False)):
        scores += [FamilyScore(family, m, 50, 40 if scored else 3, p, 0.5, scored) for m in 'EFHR']
    text = generalization_markdown(scores)
    assert '| worst family (by precision) |  | 0.600 / 0.500 (b) |' in text
    assert '| mean of the scored families |  | 0.750 / 0.500 |' in text
    assert '0.100 / 0.500 (3*)' in text and 'fewer than 30 positives' in text
    # a model that never said yes on a scored family: no precision, and that family is worst
    never = [FamilyScore('d', m, 50, 40, float('nan'), 0.0, True) for m in 'EFHR']
    text = generalization_markdown(scores + never, min_positives=12)
    assert '| worst family (by precision) |  | - / 0.000 (d) |' in text
    assert '| mean of the scored families |  | 0.750 / 0.333 |' in text
    assert 'fewer than 12 positives' in text


def _cli_files(tmp_path):
    """A pair table of four sequences and the families file of FAMILIES_YAML, in tmp_path."""
    path = tmp_path / 'pairs.csv'
    write_table(_table_of(['fx_a', 'far_s1', 'floor_far', 'wall_x']), path)
    families = tmp_path / 'families.yaml'
    families.write_text(FAMILIES_YAML)
    return path, families


def test_cli_writes_the_generalization_table(tmp_path, capsys):
    path, families = _cli_files(tmp_path)
    out = tmp_path / 'gen.md'
    args = ['train', str(path), '--out', str(out), '--leave-family-out', str(families)]
    assert main([*args, '--folds', '3']) == 0
    text = out.read_text()
    assert text.startswith('# Leave one family out (reserved, not in any fold: walls)')
    assert '| fx | 60 |' in text and '| walls |' not in text
    assert text in capsys.readouterr().out
    assert main([*args, '--folds', '3', '--final-test']) == 0
    assert '| walls | 60 |' in out.read_text()
    assert main(['train', str(path), '--out', str(out), '--final-test']) == 1
    assert '--final-test and --family-cap need --leave-family-out' in capsys.readouterr().err
    assert main([*args, '--distill', str(out)]) == 1
    assert 'not with --distill' in capsys.readouterr().err


def test_cli_trains_on_family_folds_and_refuses_their_options_without_them(tmp_path, capsys):
    import json

    path, families = _cli_files(tmp_path)
    out = tmp_path / 'models.json'
    base = ['train', str(path), '--out', str(out), '--validation-groups', 'family']
    assert main([*base, '--scene-families', str(families), '--family-precision', '0.7']) == 0
    training = json.loads(out.read_text())['metadata']['training']
    assert training['validation_groups'] == 'family' and set(training['scene_families']) == {
        'fx', 'desk', 'floor', 'walls'}  # fmt: skip
    assert 'at precision 0.7 on the worst family' in training['validation']
    # a sequence in no family, and the family options without family folds: clear errors
    assert main([*base, '--scene-families', str(tmp_path / 'missing.yaml')]) == 1
    assert 'cannot read the families file' in capsys.readouterr().err
    assert main(['train', str(path), '--out', str(out), '--family-precision', '0.7']) == 1
    assert 'with --validation-groups family only' in capsys.readouterr().err
    families.write_text('families:\n  desk: [far_*]\n')
    assert main([*base, '--scene-families', str(families)]) == 1
    assert 'sequences in no family' in capsys.readouterr().err


def test_a_family_cap_thins_large_families_for_training_and_scores_all_held_out_pairs(
    monkeypatch,
):
    import initsel_ros.learn.generalize as generalize
    from initsel_ros.learn.generalize import cap_families

    table = _table_of(['fx_a'] * 3 + ['far_s1', 'floor_far'], n=300)  # fx: 180, the others 60
    families = Families({'fx': ('fx_*',), 'desk': ('far_*',), 'floor': ('floor_*',)})
    assigned = families.assign(table['sequence'])
    keep = cap_families(table, assigned, 50, seed=0)
    assert {f: int((keep & (assigned == f)).sum()) for f in ('fx', 'desk', 'floor')} == {
        'fx': 50,
        'desk': 50,
        'floor': 50,
    }
    assert cap_families(table, assigned, None).all()
    with pytest.raises(ConfigError, match='at least 1 pair'):
        cap_families(table, assigned, 0)
    sizes: list[int] = []

    def spy(train, config):
        sizes.append(len(train))
        return train_models(train, config)

    monkeypatch.setattr(generalize, 'train_models', spy)
    scores = leave_family_out(table, families, TrainConfig(folds=3), 5, family_cap=50)
    assert sizes == [100, 100, 100]
    assert [s.pairs for s in scores[::4]] == [180, 60, 60]  # held out: every pair


def test_h_by_the_fire_path_counts_the_pairs_a_models_yes_hands_it_and_it_publishes_h_on():
    """Live, R's yes silences F and E, not H: H's yes alone still starts the fire path, which
    may publish H where E fired too; its pose is good within the labels' E_t bound."""
    n = 8
    table = PairTable(
        {
            'fire_method': np.array(['H', 'H', 'H', 'E', 'H', 'none', 'H', 'H'], dtype=object),
            'fire_et': np.array([0.05, 1.2, 0.05, 0.02, 0.05, np.nan, 0.3, 0.05]),
            'n_tracks': np.array([300, 300, 300, 300, 300, 300, 300, 300]),
        }
    )
    probabilities = {  # over (1) or under (0) thresholds of 0.5
        'E': np.array([1, 1, 1, 1, 0, 0, 0, 0], float),
        'F': np.zeros(n),
        'H': np.array([0, 0, 0, 0, 1, 1, 1, 0], float),
        'R': np.array([0, 0, 1, 0, 1, 0, 0, 0], float),
    }
    half = dict.fromkeys('FEHR', 0.5)
    published, good = fire_path_h(table, probabilities, half, et_max=0.8)
    # pair 2: only E fired, and R vetoed it; pair 4: H fired with R, and H is not vetoed;
    # pair 7: no model fired, so the fire path's H there is never run
    assert list(np.flatnonzero(published)) == [0, 1, 4, 6]
    assert list(np.flatnonzero(good)) == [0, 4, 6]
    assert list(np.flatnonzero(fire_path_h(table, probabilities, half, et_max=0.1)[1])) == [0, 4]
    # fewer tracks than the policy's min_tracks: the node decides nothing on such a frame
    few = PairTable({**table.columns, 'n_tracks': np.array([40, 300, 300, 300, 49, 300, 50, 300])})
    assert list(np.flatnonzero(fire_path_h(few, probabilities, half)[0])) == [1, 6]


def test_the_fire_path_row_is_scored_and_shown_when_the_tables_hold_it():
    table = _table_of(['far_s1'])
    models = train_models(table, TrainConfig(folds=3)).models
    scores = score_family(models, table, 'desk')
    assert FIRE_H not in {s.model for s in scores}
    cols = dict(table.columns)
    rng = np.random.default_rng(1)
    cols['fire_method'] = rng.choice(np.array(['E', 'H', 'none'], dtype=object), len(table))
    cols['fire_et'] = rng.uniform(0.0, 1.0, len(table))
    cols['n_tracks'] = np.full(len(table), 300)  # (the synthetic table's are too few to decide)
    held = PairTable(cols)
    scores = {s.model: s for s in score_family(models, held, 'desk', et_max=0.5)}
    X = held.matrix(input_columns(models.input_names, models.scaling))
    probs = models.predict_proba_batch(X)
    published, good = fire_path_h(held, probs, models.thresholds, et_max=0.5)
    y = np.asarray(held['H_label']).astype(bool)
    assert published.any()
    assert scores[FIRE_H].precision == pytest.approx(good.sum() / published.sum())
    assert scores[FIRE_H].recall == pytest.approx((published & y).sum() / y.sum())
    text = generalization_markdown(list(scores.values()))
    assert f'{FIRE_H}: good share / recall' in text and 'the best of the decompositions' in text
