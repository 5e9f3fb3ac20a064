"""Labels: exact ground truth per camera frame (2D boxes, visibility, 3D boxes, keypoints).

Pure core: :func:`zebra_sim_ros.labels.labeller.label_view` takes a scene, one camera's instance mask,
depth image and intrinsics, and returns the label dictionary the ``labeller`` node publishes and the
dataset writers store.
"""
