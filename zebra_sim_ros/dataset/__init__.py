"""Datasets: generate frames with labels in process (no DDS), write YOLO and COCO, split by placement."""
