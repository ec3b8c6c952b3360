"""Datasets of the Cotton-Eye perception system.

yolo_format: reading / writing Ultralytics-YOLO label files, data.yaml and the
two folder layouts (Roboflow export and Ultralytics' own), polygon <-> mask.
yolo_dataset: a torch Dataset over such a folder with letterboxing and
augmentations, plus its collate function.
generate: labelled datasets rendered from the simulator (a package: config,
randomize, poses, seg_labels, det_labels, pipeline, cli).
"""
