"""pybullet world of Mona robots and its ROS 2 bridge (docs/design.md#mona, #ros-interface).

:mod:`sim_bridge.mona` builds the robot's URDF from its parameters,
:mod:`sim_bridge.world` is the ROS-free pybullet world (kinematic and dynamic
modes), and :mod:`sim_bridge.node` is the ``sim_bridge`` node
(``aes-sim-bridge``) that connects the world to ROS.
"""
