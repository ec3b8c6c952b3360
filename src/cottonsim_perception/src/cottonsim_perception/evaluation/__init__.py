"""Evaluation of the Cotton-Eye networks: IoU, matching, precision / recall / AP."""
