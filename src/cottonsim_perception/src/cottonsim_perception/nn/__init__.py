"""YOLOv8-style networks of the Cotton-Eye perception system, written in torch.

blocks (Conv, C2f, SPPF, backbone, neck), heads (DFL detection head, prototype
masks), models (YoloDetector, YoloSegmenter, ModelConfig, checkpoints),
assigner (task-aligned assigner), loss, postprocess (decode, NMS, masks) and
letterbox (resize with padding and its inverse).
"""
