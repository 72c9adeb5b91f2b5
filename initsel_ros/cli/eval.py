"""``initsel eval``: the paper's tables for a test set, with every baseline beside."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel eval``."""
    options.add_inputs_argument(
        parser, 'tables', 'PAIRS_CSV', 'test pair tables written by `initsel dataset`'
    )
    options.add_models_option(parser)
    options.add_out_dir_option(parser, 'write eval.md, eval.csv and the PNG plots here')
    parser.add_argument(
        '--train',
        type=Path,
        nargs='+',
        default=None,
        metavar='TRAIN_CSV',
        help='training pairs: also fit the model families in memory and '
        'compare them with the model file (thresholds by grouped '
        'cross-validation on these pairs)',
    )
    parser.add_argument(
        '--candidates',
        nargs='+',
        default=None,
        metavar='FAMILY',
        help='families to fit with --train (default: all): logistic, '
        'logistic+extra, trees, trees+extra, hgb+extra, mlp+extra',
    )
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')


def run(args: argparse.Namespace) -> int:
    """Evaluate and print the report."""
    import csv

    from initsel_ros.errors import ConfigError
    from initsel_ros.learn.candidates import Candidate
    from initsel_ros.learn.evaluate import evaluate, report_markdown, results_csv_rows
    from initsel_ros.learn.table import read_tables
    from initsel_ros.learn.train import prepare
    from initsel_ros.learn.twoview import check_labelled
    from initsel_ros.models import ModelSet

    models = ModelSet.load(options.model_path(args.models))
    test = read_tables(args.tables)
    check_labelled(test, 'evaluation')
    train = None
    config = config_like(models.metadata, models.scaling)
    if args.train:
        train_table = read_tables(args.train)
        check_labelled(train_table, "evaluation's training pairs")
        train = prepare(train_table, config)
    kwargs = {}
    if args.candidates:
        known = [c.value for c in Candidate]
        unknown = [c for c in args.candidates if c not in known]
        if unknown:
            raise ConfigError(
                f'--candidates: unknown family {", ".join(unknown)} '
                f'(choose from {", ".join(known)})'
            )
        kwargs['candidates'] = tuple(Candidate(c) for c in args.candidates)
    report = evaluate(test, models, train=train, train_config=config, **kwargs)
    text = report_markdown(report)
    print(text)
    if args.out_dir:
        out = Path(args.out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / 'eval.md').write_text(text)
        rows = results_csv_rows(report)
        with (out / 'eval.csv').open('w', newline='') as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        if not args.no_plots:
            from initsel_ros.learn.plots import write_plots

            for path in write_plots(test, models, report, out):
                print(f'wrote {path}')
        print(f'wrote {out / "eval.md"} and {out / "eval.csv"}')
    return 0


def config_like(metadata: dict, scaling: object) -> object:
    """The training options a model file records (target precision, trees, extra features),
    so candidates are fitted as the file was; defaults for anything missing or malformed."""
    from initsel_ros.errors import ConfigError
    from initsel_ros.learn.train import TrainConfig, TreeConfig

    training = metadata.get('training', {}) if isinstance(metadata, dict) else {}
    training = training if isinstance(training, dict) else {}
    kwargs: dict = {'scaling': scaling}
    target = training.get('target_precision')
    if isinstance(target, (int, float)) and 0.0 < target <= 1.0:
        kwargs['target_precision'] = float(target)
    trees = training.get('trees')
    if isinstance(trees, dict):
        with contextlib.suppress(KeyError, TypeError, ValueError, OverflowError, ConfigError):
            kwargs['trees'] = TreeConfig(
                int(trees['n_trees']), int(trees['depth']), float(trees['learning_rate'])
            )
    extra = training.get('extra_features')
    if isinstance(extra, list) and all(isinstance(n, str) for n in extra):
        kwargs['extra'] = tuple(extra)
    try:
        return TrainConfig(**kwargs)
    except ConfigError:
        return TrainConfig(scaling=scaling)
