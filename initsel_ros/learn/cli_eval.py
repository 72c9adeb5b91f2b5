"""``initsel eval``: the paper's tables for a test set, with every baseline beside."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel eval``."""
    parser.add_argument('tables', nargs='+', type=Path, metavar='PAIRS_CSV',
                        help='test pair tables written by `initsel dataset`')
    parser.add_argument('--models', type=Path, default=None,
                        help='model file (default: the packaged config/models.json)')
    parser.add_argument('--out-dir', type=Path, default=None,
                        help='write eval.md, eval.csv and the PNG plots here')
    parser.add_argument('--train', type=Path, nargs='+', default=None, metavar='TRAIN_CSV',
                        help='training pairs: also fit richer models in memory (logistic + '
                             'extra features, gradient boosting, MLP) and compare')
    parser.add_argument('--candidates', nargs='+', default=None, metavar='FAMILY',
                        choices=('logistic+extra', 'hgb+extra', 'mlp+extra'),
                        help='richer families to fit with --train (default: all three)')
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')


def run(args: argparse.Namespace) -> int:
    """Evaluate and print the report."""
    import csv

    from initsel_ros.learn.evaluate import evaluate, report_markdown, results_csv_rows
    from initsel_ros.learn.table import read_tables
    from initsel_ros.learn.train import Candidate, TrainConfig, prepare
    from initsel_ros.models import ModelSet, default_model_path

    models = ModelSet.load(args.models or default_model_path())
    test = read_tables(args.tables)
    train = None
    config = TrainConfig(scaling=models.scaling)
    target = models.metadata.get('training', {}).get('target_precision')
    if isinstance(target, (int, float)):
        config = TrainConfig(scaling=models.scaling, target_precision=float(target))
    if args.train:
        train = prepare(read_tables(args.train), config)
    kwargs = {}
    if args.candidates:
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
