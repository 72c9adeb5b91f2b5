"""``initsel orbvocab``: train the substitute DBoW2 vocabulary the real ORB-SLAM3 loads."""

from __future__ import annotations

import argparse
import sys

from initsel_ros.cli import options


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``initsel orbvocab``."""
    options.add_inputs_argument(
        parser,
        'sequences',
        'SEQUENCE',
        'sequences whose frames give the ORB descriptors (e.g. initsel synth renders)',
    )
    parser.add_argument(
        '--out', type=options.output_file, required=True, help='vocabulary file (text format)'
    )
    parser.add_argument('--k', type=int, default=10, help='branching factor (default 10)')
    parser.add_argument('--levels', type=int, default=3, help='tree depth (default 3)')
    parser.add_argument('--every', type=int, default=5, help='use every N-th frame (default 5)')
    parser.add_argument(
        '--max-frames', type=int, default=100, help='at most this many frames (default 100)'
    )
    parser.add_argument('--seed', type=int, default=0, help='k-means++ seed (default 0)')


def run(args: argparse.Namespace) -> int:
    """Train and write the vocabulary."""
    from initsel_ros.learn.real_baselines.vocabulary import train_vocabulary, training_frames

    if args.every < 1 or args.max_frames < 1:
        print('initsel orbvocab: error: --every and --max-frames must be >= 1', file=sys.stderr)
        return 2
    frames = training_frames(args.sequences, every=args.every, limit=args.max_frames)
    try:
        vocabulary = train_vocabulary(frames, k=args.k, levels=args.levels, seed=args.seed)
    except ValueError as exc:
        print(f'initsel orbvocab: error: {exc}', file=sys.stderr)
        return 2
    vocabulary.save(args.out)
    print(f'{args.out}: {vocabulary.n_words} words from {len(frames)} frames', file=sys.stderr)
    return 0
