"""YOLOv8-style networks of the Cotton-Eye perception system, written in torch.

blocks (Conv, C2f, SPPF, backbone, neck), heads (DFL detection head, prototype
masks), models (YoloDetector, YoloSegmenter, ModelConfig, checkpoints),
assigner (task-aligned assigner), loss, postprocess (decode, NMS, masks),
letterbox (resize with padding and its inverse) and optimize (the frozen
channels-last TorchScript graph that inference runs).
"""
