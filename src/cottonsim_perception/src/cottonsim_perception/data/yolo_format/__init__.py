"""Ultralytics-YOLO dataset format: label files, data.yaml, folder layouts, masks.

Why: the paper's data (Roboflow export of the original CottonSim datasets) and
the datasets our generator writes are in this format, and both training and
evaluation read it; one careful reader means one set of error messages.

Modules (import from this package; the names below are its API):

* ``labels``: label lines and files (``LabelInstance``, ``parse_label_line``,
  ``read_label_file``, ``write_label_file``, ``LabelFormatError``);
* ``data_yaml``: Ultralytics' data.yaml (``DataYaml``, ``read_data_yaml``,
  ``write_data_yaml``, ``class_names_for``);
* ``layout``: where a split's images, labels and ignore boxes are
  (``list_pairs``, ``label_path_for``, ``ignore_path_for``,
  ``read_ignore_boxes``): a data.yaml's split keys, the Roboflow export
  ``DIR/{train,valid,test}/images`` or Ultralytics' ``DIR/images/{train,val,test}``;
* ``masks``: polygon <-> mask (``polygon_to_mask``, ``mask_to_polygons``),
  joining a class's polygons into one line (``join_polygons``,
  ``merge_instances_per_class``, ``merge_seg_label_files``) and labels as
  pixel arrays (``instances_to_pixels``).

Pixel convention: pixel-edge coordinates, x right, y down; a polygon point
(1, 1) normalised is the bottom-right corner (W, H) [px] of the image.
"""
from .data_yaml import DATA_YAML, DataYaml, class_names_for, read_data_yaml, write_data_yaml
from .labels import (DEFAULT_RANGE_TOLERANCE, DETECTION_CLASS_NAMES, SEGMENTATION_CLASS_NAMES, TASKS,
                     LabelFormatError, LabelInstance, format_label_line, parse_label_line,
                     polygon_bbox_cxcywh, polygon_bbox_xyxy, read_label_file, write_label_file)
from .layout import (IGNORE_FOLDER, IMAGE_EXTENSIONS, ImageLabelPair, ignore_path_for, label_path_for,
                     list_pairs, read_ignore_boxes, read_ignore_instances)
from .masks import (instances_to_pixels, join_polygons, mask_to_polygons, merge_instances_per_class,
                    merge_seg_label_files, polygon_to_mask)

__all__ = [
    "DATA_YAML", "DataYaml", "class_names_for", "read_data_yaml", "write_data_yaml",
    "DEFAULT_RANGE_TOLERANCE", "DETECTION_CLASS_NAMES", "SEGMENTATION_CLASS_NAMES", "TASKS",
    "LabelFormatError", "LabelInstance", "format_label_line", "parse_label_line",
    "polygon_bbox_cxcywh", "polygon_bbox_xyxy", "read_label_file", "write_label_file",
    "IGNORE_FOLDER", "IMAGE_EXTENSIONS", "ImageLabelPair", "ignore_path_for", "label_path_for",
    "list_pairs", "read_ignore_boxes", "read_ignore_instances",
    "instances_to_pixels", "join_polygons", "mask_to_polygons", "merge_instances_per_class",
    "merge_seg_label_files", "polygon_to_mask",
]
