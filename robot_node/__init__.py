"""AES robot nodes: one rclpy node per robot (``aes-robot-node``) or K per process
(``aes-robot-host``), each publishing the control law of :func:`aes_ros.model.robot_command`."""
