"""Harvest cores: the vacuum nozzle's capture rule and the fusion of boll detections into targets."""
