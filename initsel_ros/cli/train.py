"""``initsel train``: fit the F/E/H/R models into a JSON model file."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from initsel_ros.cli import options

FAMILIES = ('logistic', 'logistic+extra', 'trees', 'trees+extra')
PAPER = (  # features.FEATURE_NAMES
    'count',
    'disparity_mean',
    'disparity_std',
    *(f'{c}_{m}' for c in ('x0', 'y0', 'x1', 'y1') for m in ('min', 'max')),
    *(f'{c}_range' for c in ('x0', 'y0', 'x1', 'y1')),
    *(f'direction_{45 * k}' for k in range(8)),
)
#: learn.labels.ROTATION_LABELS and METHOD_LABELS (not imported: --help loads no OpenCV)
ROTATION_LABELS = ('baseline', 'parallax', 'flow', 'test')
METHOD_LABELS = ('good', 'best', 'determined')
EXTRA = (  # features.EXTRA_FEATURE_NAMES (not imported: --help loads no OpenCV)
    'x_disp_p10',
    'x_disp_p50',
    'x_disp_p90',
    'x_grid_occupancy',
    'x_grid_entropy',
    'x_affine_residual',
    'x_homography_residual',
    'x_flow_mean_x',
    'x_flow_mean_y',
    'x_flow_coherence',
    'x_flow_spread',
    'x_point_spread',
    'x_affine_divergence',
    'x_affine_curl',
    'x_affine_deformation',
    'x_homography_dlt_residual',
    'x_rotation_departure',
    'x_rotation_departure_focal',
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel train``."""
    options.add_inputs_argument(
        parser, 'tables', 'PAIRS_CSV', 'pair tables written by `initsel dataset`'
    )
    parser.add_argument(
        '--out',
        required=True,
        type=options.output_file,
        help='model file to write (JSON); with --leave-family-out, the Markdown table',
    )
    parser.add_argument(
        '--threshold-prior',
        action='append',
        default=[],
        metavar='[MODEL=]SHARE',
        help='measure the validation precision as if positives were this share of the pairs '
        "(0-1), not the training mix's own share: thresholds that do not move with the mix; "
        'MODEL=SHARE for one model (repeat)',
    )
    parser.add_argument(
        '--target-precision',
        type=float,
        default=0.8,
        help='choose each threshold for this validation precision (default 0.8)',
    )
    parser.add_argument(
        '--family',
        action='append',
        default=[],
        metavar='[MODEL=]FAMILY',
        help='model family: ' + ', '.join(FAMILIES) + '; FAMILY alone sets '
        'every model, F=FAMILY one model; repeatable (default '
        'trees+extra: gradient-boosted trees on the 23 features plus the '
        'extra ones)',
    )
    parser.add_argument(
        '--extra-features',
        nargs='+',
        default=None,
        metavar='NAME',
        choices=EXTRA,
        help='extra features the +extra families read (default all: ' + ', '.join(EXTRA) + ')',
    )
    parser.add_argument(
        '--paper-features',
        nargs='+',
        default=None,
        metavar='NAME',
        choices=PAPER,
        help="the paper's 23 features the +extra families read (default all of them; the "
        'plain families read all 23)',
    )
    parser.add_argument(
        '--validation-groups',
        choices=('batch', 'sequence', 'family'),
        default='batch',
        help='unit of the cross-validation folds that choose the thresholds (default batch; '
        'sequence: thresholds for sequences the models were not fitted on; family: one fold '
        'per scene family of --scene-families, and the target precision must hold on the '
        'worst family with at least 30 positives too: thresholds for scenes never seen)',
    )
    parser.add_argument(
        '--scene-families',
        type=Path,
        default=None,
        metavar='FAMILIES',
        help='the scene families of --validation-groups family (default: the file of '
        '--leave-family-out, else the packaged config/families.yaml)',
    )
    parser.add_argument(
        '--family-precision',
        type=float,
        default=None,
        metavar='P',
        help='with --validation-groups family: the precision the worst family must reach '
        '(default: --target-precision)',
    )
    parser.add_argument(
        '--leave-family-out',
        type=Path,
        default=None,
        metavar='FAMILIES',
        help='instead of writing a model file, measure generalization: for each scene family '
        'of this YAML file (config/families.yaml) retrain by these options without it and '
        'score it at thresholds chosen without it; writes the per-family table to --out',
    )
    parser.add_argument(
        '--family-cap',
        type=int,
        default=None,
        metavar='PAIRS',
        help='with --leave-family-out: train on at most this many random pairs of each family '
        '(default: all), so that one large family does not set the class balance',
    )
    parser.add_argument(
        '--rotation-min-static-share',
        type=float,
        default=None,
        metavar='SHARE',
        help="leave out of R's training the R-positive pairs whose tracks the ground truth "
        'explains as a static scene for less than this share of them (objects moving on '
        'their own; the gt_static_share column; default: R learns from every pair)',
    )
    parser.add_argument(
        '--final-test',
        action='store_true',
        help="with --leave-family-out: score the file's reserved family instead, once, with "
        'the models trained on every other family',
    )
    parser.add_argument(
        '--distill',
        type=Path,
        default=None,
        metavar='TEACHER',
        help='instead of learning the labels, fit each model (trees) to the logits of this '
        "model file on the tables' pairs and keep its thresholds: the same decisions from "
        'the inputs --paper-features and --extra-features name (labels are not read)',
    )
    parser.add_argument(
        '--referee',
        nargs='+',
        default=(),
        choices=('F', 'E', 'H', 'R'),
        metavar='MODEL',
        help="with --distill: keep the teacher's MODEL in the file as a referee that decides "
        'the pairs on which the student is unsure, within a band of the threshold holding 90 %% '
        'of the out-of-fold disagreements with the teacher (docs/learning.md)',
    )
    parser.add_argument(
        '--trees', type=int, default=100, help='boosting stages of the tree families (default 100)'
    )
    parser.add_argument(
        '--tree-depth', type=int, default=3, help='maximum depth of each tree (default 3)'
    )
    parser.add_argument(
        '--learning-rate', type=float, default=0.1, help='shrinkage of each tree (default 0.1)'
    )
    parser.add_argument(
        '--C',
        dest='C',
        type=float,
        default=1.0,
        help='inverse L2 regularization of LogisticRegression (default 1)',
    )
    parser.add_argument(
        '--class-weight',
        choices=('balanced', 'none'),
        default='balanced',
        help='class weighting (default balanced: F positives are rare)',
    )
    parser.add_argument(
        '--scaling',
        choices=('resolution_free', 'paper'),
        default='resolution_free',
        help='feature scaling (default resolution_free; identical to paper at 640x480)',
    )
    parser.add_argument(
        '--folds',
        type=options.whole_number(2),
        default=5,
        help='grouped cross-validation folds over batches (default 5)',
    )
    parser.add_argument('--seed', type=int, default=0, help='random seed (default 0)')
    parser.add_argument(
        '--allow-degenerate',
        action='store_true',
        help='write a model whose training labels are all one class (it '
        'always or never fires); by default that is an error',
    )
    labels = parser.add_argument_group('relabel (default: the labels stored in the table)')
    labels.add_argument('--et-max', type=float, default=None, help='E_t threshold (0.8)')
    labels.add_argument('--er-max', type=float, default=None, help='E_R threshold, m (1.0)')
    labels.add_argument(
        '--rotation-baseline',
        type=float,
        default=None,
        help='R label: baseline at most this, m (0.05)',
    )
    labels.add_argument(
        '--rotation-label',
        choices=ROTATION_LABELS,
        default=None,
        help="R label rule: the paper's baseline (default), the pair's median ground-truth "
        "parallax angle under --rotation-parallax, or 'flow' (the rotation alone explains "
        "at least 80%% of the tracks' true flow within 2.5 px: the gt_rotation_share column), "
        "or 'test' (the node's rotation test leaves under 3 times the noise on the pair's "
        'tracks: fire_rotation_statistic, from initsel dataset --fire-path; not ground truth); '
        'rows without them keep the baseline rule',
    )
    labels.add_argument(
        '--rotation-parallax',
        type=float,
        default=None,
        help='R label with --rotation-label parallax: median parallax under this, deg (1.0)',
    )
    labels.add_argument(
        '--method-label',
        choices=METHOD_LABELS,
        default=None,
        help="F, E, H label rule: 'good' (the paper's: the method's own pose is good), "
        "'best' (good, and within --best-margin E_t of the pair's best good pose: a method "
        "the pair should be initialized with) or 'determined' (good, and the scene fixes "
        'the method: E and F need under 80%% of the tracks on one plane, H at least 80%%; '
        'the gt_plane_share column)',
    )
    labels.add_argument(
        '--best-margin',
        type=float,
        default=None,
        help='E_t margin of --method-label best (0.05)',
    )
    options.add_scale_rule_option(labels, None, 'E_R scale rule')


def run(args: argparse.Namespace) -> int:
    """Read the tables, train, write the model file."""
    from initsel_ros.errors import ConfigError
    from initsel_ros.features import Scaling
    from initsel_ros.learn.labels import LabelConfig, ScaleRule
    from initsel_ros.learn.table import read_tables
    from initsel_ros.learn.train import (
        DEFAULT_FAMILY,
        ClassWeight,
        Family,
        TrainConfig,
        TreeConfig,
        describe_inputs,
        train_models,
    )
    from initsel_ros.markdown import markdown_table

    if not 0.0 < args.target_precision <= 1.0:
        raise ConfigError(f'--target-precision must be in (0, 1], got {args.target_precision}')
    if args.C <= 0:
        raise ConfigError(f'--C must be positive, got {args.C}')
    relabel_given = {
        'et_max': args.et_max,
        'er_max': args.er_max,
        'rotation_baseline_m': args.rotation_baseline,
        'rotation_label': args.rotation_label,
        'rotation_parallax_deg': args.rotation_parallax,
        'method_label': args.method_label,
        'best_margin': args.best_margin,
        'scale_rule': None if args.scale_rule is None else ScaleRule(args.scale_rule),
    }
    relabel_given = {k: v for k, v in relabel_given.items() if v is not None}
    # the options not given keep LabelConfig's defaults; none given: the table's own labels
    relabel = LabelConfig(**relabel_given) if relabel_given else None
    family, families = DEFAULT_FAMILY, {}
    for spec in args.family:
        model, _, name = spec.rpartition('=')
        if name not in FAMILIES or (model and model not in ('F', 'E', 'H', 'R')):
            raise ConfigError(
                f'--family {spec!r}: expected FAMILY or MODEL=FAMILY with '
                f'MODEL in F, E, H, R and FAMILY in {", ".join(FAMILIES)}'
            )
        if model:
            families[model] = Family(name)
        else:
            family, families = Family(name), {}
    prior, priors = None, {}
    for spec in args.threshold_prior:
        model, _, share = spec.rpartition('=')
        try:
            value = float(share)
        except ValueError:
            message = f'--threshold-prior {spec!r}: expected SHARE or MODEL=SHARE'
            raise ConfigError(message) from None
        if model:
            priors[model] = value
        else:
            prior = value
    scene_families = None
    if args.validation_groups == 'family':
        from initsel_ros.config_files import find_config_file
        from initsel_ros.learn.generalize import Families

        scene_families = Families.load(
            args.scene_families or args.leave_family_out or find_config_file('families.yaml')
        )
    elif args.scene_families is not None or args.family_precision is not None:
        raise ConfigError(
            '--scene-families and --family-precision are read with --validation-groups family only'
        )
    config = TrainConfig(
        scaling=Scaling(args.scaling),
        C=args.C,
        class_weight=ClassWeight(args.class_weight),
        target_precision=args.target_precision,
        threshold_prior=prior,
        threshold_priors=priors,
        folds=args.folds,
        group_by=args.validation_groups,
        seed=args.seed,
        labels=relabel,
        allow_degenerate=args.allow_degenerate,
        family=family,
        families=families,
        trees=TreeConfig(args.trees, args.tree_depth, args.learning_rate),
        rotation_min_static_share=args.rotation_min_static_share,
        scene_families=scene_families,
        family_precision=args.family_precision,
        **({'extra': tuple(args.extra_features)} if args.extra_features else {}),
        **({'paper': tuple(args.paper_features)} if args.paper_features else {}),
    )
    if (args.final_test or args.family_cap is not None) and args.leave_family_out is None:
        raise ConfigError('--final-test and --family-cap need --leave-family-out FAMILIES')
    if args.referee and args.distill is None:
        raise ConfigError('--referee keeps a teacher model: it needs --distill TEACHER')
    if args.leave_family_out is not None and args.distill is not None:
        raise ConfigError('--leave-family-out retrains from the labels: not with --distill')
    table = read_tables(args.tables)
    if args.distill is None:
        from initsel_ros.learn.twoview import check_labelled

        check_labelled(table, 'training from labels')
    if args.leave_family_out is not None:
        return _leave_family_out(args, table, config)
    if args.distill is not None:
        return _distill(args, table, config)
    report = train_models(
        table, config, description=describe_inputs([p.name for p in args.tables])
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    report.models.save(args.out)
    print(f'{args.out}: trained on {report.n_pairs} pairs in {report.n_batches} batches')
    columns = ('model', 'family', 'positives', 'threshold', 'val. precision', 'val. recall')
    columns += ('val. F1', 'target')
    rows = [
        (
            m,
            report.models.models[m].metrics.get('family', ''),
            report.positives[m],
            *(f'{v:.3f}' for v in (c.threshold, c.precision, c.recall, c.f1)),
            'reached' if c.reached else 'not reached',
        )
        for m, c in report.choices.items()
    ]
    print(markdown_table(columns, rows))
    return 0


def _leave_family_out(args: argparse.Namespace, table: Any, config: Any) -> int:
    """``initsel train --leave-family-out``: the per-family generalization table."""
    from initsel_ros.learn.generalize import (
        Families,
        final_test,
        generalization_markdown,
        leave_family_out,
    )

    families = Families.load(args.leave_family_out)
    if args.final_test:
        scores = final_test(table, families, config, family_cap=args.family_cap)
        title = f'Final test: the reserved family {families.reserved}, trained on all others'
    else:
        scores = leave_family_out(table, families, config, family_cap=args.family_cap)
        title = 'Leave one family out'
        if families.reserved:
            title += f' (reserved, not in any fold: {families.reserved})'
    if args.family_cap is not None:
        title += f', at most {args.family_cap} training pairs a family'
    text = f'# {title}\n\n{generalization_markdown(scores)}\n'
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(text, end='')
    return 0


def _distill(args: argparse.Namespace, table: Any, config: Any) -> int:
    """``initsel train --distill``: fit students to the teacher's logits, print agreement."""
    from initsel_ros.learn.distill import distill_models
    from initsel_ros.learn.train import describe_inputs
    from initsel_ros.markdown import markdown_table
    from initsel_ros.models import ModelSet

    teacher = ModelSet.load(args.distill)
    features = config.paper + config.extra
    report = distill_models(
        table,
        teacher,
        features,
        config.trees,
        seed=args.seed,
        description=describe_inputs([p.name for p in args.tables]),
        referee=tuple(args.referee),
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    report.models.save(args.out)
    print(f'{args.out}: distilled from {args.distill} on {report.n_pairs} pairs')
    rows = [
        (
            m,
            f'{teacher.models[m].threshold:.3f}',
            f'{report.agreement[m]:.3f}',
            f'{report.logit_rmse[m]:.2f}',
        )
        for m in report.models.models
    ]
    print(markdown_table(('model', 'threshold', 'agreement', 'logit RMSE'), rows))
    for m, band in report.referee.items():
        print(
            f'referee {m}: band +-{band.band_logit:g} logits around the threshold; out of fold '
            f'the student agrees with the teacher on {band.out_of_fold_agreement:.3f} of the '
            f'pairs, the band holds {band.captured:.3f} of the disagreements and '
            f'{band.referred:.3f} of the pairs'
        )
    return 0
