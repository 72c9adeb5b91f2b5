"""The real systems as seed-map baselines, beside the re-implemented rules.

- :mod:`.colmap`: COLMAP's calibrated two-view geometry (pycolmap, the ``test`` extra) on the
  selector's own KLT tracks: row ``COLMAP (real)``.
- :mod:`.orbslam3_runner`: the real ORB-SLAM3 monocular system (the ``orbslam3-python``
  wheel, GPL-3, in a venv of its own made by ``scripts/setup_orbslam3.sh``), fed the batch's
  frames in a subprocess (:mod:`.orbslam3_worker`): row ``ORB-SLAM3 (real)``.
  :mod:`.vocabulary` trains the substitute DBoW2 vocabulary it needs.

Neither is a dependency of the node: both are imported only by ``initsel seedmap``.
"""
