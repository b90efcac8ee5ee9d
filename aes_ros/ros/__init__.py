"""Shared ROS 2 helpers: QoS profiles, message conversions, parameter descriptors.

The only part of ``aes_ros`` that imports rclpy; the model never does.
"""
