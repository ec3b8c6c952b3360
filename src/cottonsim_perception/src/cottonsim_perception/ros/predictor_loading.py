"""Loading a network for a perception node from its ~params, without ever taking the node down.

Shared by the segmentation and boll detection nodes. Parameters read (private):
  ~device (str, 'cpu'), ~conf_threshold (float, 0.25), ~iou_threshold (float, 0.7), ~threads (int, 1),
  ~mask_threshold (float, -1: the value calibrated for the weights and stored in them, else 0.5;
  segmentation weights only).
"""
import os
from typing import Optional

import rospy


def load_predictor(node: str, weights: str, source_param: str, expected_task: Optional[str] = None):
    """The Predictor for ``weights``, or None after logging an error that names the path and the problem.

    node: the node's name for log lines; source_param: the parameter that asked for the network
    (e.g. '~mask_source'); expected_task: 'seg' or 'det' to refuse a checkpoint of the other kind.
    """
    if not weights:
        rospy.logerr("%s: %s is 'network' but ~weights is empty; publishing nothing", node, source_param)
        return None
    if not os.path.isfile(weights):
        rospy.logerr("%s: weights file '%s' does not exist; publishing nothing", node, weights)
        return None
    try:
        from cottonsim_perception.inference import Predictor
        mask_threshold = float(rospy.get_param("~mask_threshold", -1.0))
        predictor = Predictor(weights, device=str(rospy.get_param("~device", "cpu")),
                              conf_threshold=float(rospy.get_param("~conf_threshold", 0.25)),
                              iou_threshold=float(rospy.get_param("~iou_threshold", 0.7)),
                              threads=int(rospy.get_param("~threads", 1)),
                              mask_threshold=None if mask_threshold < 0 else mask_threshold)
    except Exception as exc:  # a bad checkpoint must not take the node down
        rospy.logerr("%s: cannot load weights '%s': %s; publishing nothing", node, weights, exc)
        return None
    if expected_task is not None and predictor.task != expected_task:
        rospy.logerr("%s: weights '%s' are a '%s' model, not a '%s' model; publishing nothing", node, weights,
                     predictor.task, expected_task)
        return None
    return predictor
