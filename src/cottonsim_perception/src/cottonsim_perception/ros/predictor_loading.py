"""Loading a network for a perception node from its ~params, without ever taking the node down.

Shared by the segmentation and boll detection nodes. Parameters read (private):
  ~backend (str, 'onnxruntime': the .onnx export beside ~weights; 'torch'), ~device (str, 'cpu'),
  ~conf_threshold (float, 0.25), ~iou_threshold (float, 0.7), ~threads (int, 1),
  ~mask_threshold (float, -1: the value calibrated for the weights and stored in them, else 0.5;
  segmentation weights only).
"""
import os
from typing import NamedTuple, Optional

import rospy

from cottonsim_perception.nn.backends import BACKENDS


class LoadedNetwork(NamedTuple):
    """predictor: the Predictor, or None when it did not load; backend: 'onnxruntime' | 'torch' | 'none';
    error: why there is no predictor ('' when there is)."""

    predictor: object
    backend: str
    error: str


def backend_from_params() -> str:
    """~backend, checked (ValueError names the parameter and the choices)."""
    backend = str(rospy.get_param("~backend", "onnxruntime"))
    if backend not in BACKENDS:
        raise ValueError(f"~backend must be one of {BACKENDS}, got '{backend}'")
    return backend


def _predictor(weights: str, backend: str):
    from cottonsim_perception.inference import Predictor

    mask_threshold = float(rospy.get_param("~mask_threshold", -1.0))
    return Predictor(weights, device=str(rospy.get_param("~device", "cpu")),
                     conf_threshold=float(rospy.get_param("~conf_threshold", 0.25)),
                     iou_threshold=float(rospy.get_param("~iou_threshold", 0.7)),
                     threads=int(rospy.get_param("~threads", 1)),
                     mask_threshold=None if mask_threshold < 0 else mask_threshold, backend=backend)


def load_predictor(node: str, weights: str, source_param: str, expected_task: Optional[str] = None,
                   backend: str = "onnxruntime") -> LoadedNetwork:
    """The network for ``weights`` on ``backend``; without one, an error logged once naming the path and the problem.

    node: the node's name for log lines; source_param: the parameter that asked for the network
    (e.g. '~mask_source'); expected_task: 'seg' or 'det' to refuse a checkpoint of the other kind.
    An onnxruntime backend that cannot run (no export, an export of other weights) falls back to
    torch with a warning; a checkpoint that does not load leaves the node up without a network.
    """
    def failed(reason: str) -> LoadedNetwork:
        rospy.logerr("%s: %s; the node stays up, publishes no %s results and reports backend 'none' "
                     "on /cotton_eye/health", node, reason, node)
        return LoadedNetwork(None, "none", reason)

    if not weights:
        return failed(f"{source_param} is 'network' but ~weights is empty")
    if not os.path.isfile(weights):
        return failed(f"weights file '{weights}' does not exist")
    predictor = None
    try:
        predictor = _predictor(weights, backend)
    except Exception as exc:  # a bad checkpoint or export must not take the node down
        if backend == "onnxruntime":
            rospy.logwarn("%s: onnxruntime backend unavailable (%s); trying the torch backend", node, exc)
            backend = "torch"
            try:
                predictor = _predictor(weights, backend)
            except Exception as exc_torch:
                return failed(f"cannot load weights '{weights}': {exc_torch}")
        else:
            return failed(f"cannot load weights '{weights}': {exc}")
    if expected_task is not None and predictor.task != expected_task:
        return failed(f"weights '{weights}' are a '{predictor.task}' model, not a '{expected_task}' model")
    rospy.loginfo("%s: %s network '%s' on the %s backend", node, predictor.task, weights, backend)
    return LoadedNetwork(predictor, backend, "")
