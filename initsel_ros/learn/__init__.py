"""Offline learning: labelled pairs, training, evaluation against the baselines.

Modules (imported on demand, so ``initsel --help`` stays light):

- :mod:`~initsel_ros.learn.pairs`: batches, KLT/ORB correspondences, one table row per pair.
- :mod:`~initsel_ros.learn.labels`: E_t, E_R against ground truth; F/E/H/R labels.
- :mod:`~initsel_ros.learn.table`: the CSV pair table and its schema.
- :mod:`~initsel_ros.learn.train`: logistic models, thresholds for a target precision, richer
  in-memory candidates.
- :mod:`~initsel_ros.learn.evaluate`: the paper's tables, baselines, sequence-level figures.
- :mod:`~initsel_ros.learn.baselines`: Butt et al. 2020, VINS-Mono, ORB-SLAM2/3 rules
  (re-implemented).
- :mod:`~initsel_ros.learn.seedmap`: the published seed map against the baselines.
- :mod:`~initsel_ros.learn.real_baselines`: the real ORB-SLAM3 (own venv, subprocess) and
  COLMAP (pycolmap) as seed-map baselines; the substitute ORB vocabulary.
- :mod:`~initsel_ros.learn.plots`: precision-recall and error-vs-baseline figures.
"""

from __future__ import annotations

__all__ = ['baselines', 'evaluate', 'labels', 'pairs', 'plots', 'table', 'train']
