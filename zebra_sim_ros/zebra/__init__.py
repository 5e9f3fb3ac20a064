"""The procedural articulated zebra: the simulation's main character.

Frame of the asset: metres, x forward, y left, z up (REP 103 body frame); the origin lies on the
ground plane under the middle of the body, so a standing zebra's hooves touch z = 0.

- ``skeleton``   joints, body proportions (morphs: plains, Grévy's, foal) and forward kinematics
- ``mesh``       the skin: a closed mesh swept along the bones, UVs, skinning weights, two levels of detail
- ``animation``  the in-place clips (idle, graze, walk, trot, gallop, ...) as joint rotations per frame
- ``skinning``   linear-blend skinning
- ``keypoints``  named body keypoints and their skeleton edges
- ``coat``       per-individual procedural stripe textures
- ``asset``      baking every clip frame (vertices, joints, keypoints, boxes) into a fast cache
- ``usd``        the UsdSkel asset writer
- ``preview``    a contact sheet of poses
"""
