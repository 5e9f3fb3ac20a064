"""Detection: our one-stage YOLO-family detector in plain torch, its training, evaluation and export.

- ``model``    CSP backbone, PAN neck, anchor-free decoupled head (DFL box regression); sizes n and s
- ``boxes``    box conversions, IoU variants, the distance (ltrb) box codec, batched NMS
- ``loss``     task-aligned assigner, CIoU + DFL + BCE losses
- ``data``     YOLO-format datasets with letterbox, mosaic, random affine, flip and HSV augmentation
- ``metrics``  COCO-style AP (IoU 0.50:0.05:0.95, 101-point interpolation), precision, recall, PR curves
- ``train``    the training loop (warm-up, cosine, EMA, AMP, checkpoints, resume, DDP under torchrun)
- ``evaluate`` validation of a checkpoint on a YOLO-format set
- ``predict``  checkpoint loading and inference on images
"""
