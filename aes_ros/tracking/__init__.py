"""Overhead-camera tracking without ROS: finding the markers (:mod:`.detection`), the
camera's pose from reference markers (:mod:`.calibration`, :mod:`.camera_info`), robot
poses from marker corners (:mod:`.pose`) and what is known of each robot between frames
(:mod:`.tracks`). The tracker node (``aes-tracker``) and ``aes-swarm calibrate`` adapt it
(docs/design.md#tracking)."""
