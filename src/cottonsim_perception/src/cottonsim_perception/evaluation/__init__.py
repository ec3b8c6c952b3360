"""Evaluation of the Cotton-Eye networks: IoU, matching, precision / recall / AP.

metrics: IoU, matching and AP (Ultralytics' definitions); splits: a network
on labelled splits, the result dicts of the paper's Table 3; cli: the
``evaluate`` command; box_errors, mask_errors, resolution, calibration,
paper: analyses and tables built on them.
"""
