"""The Mona robot without ROS: its geometry and the Mona link v1 (docs/mona_protocol.md).

- :mod:`aes_ros.mona.geometry`: dimensions and motor limits, shared by the simulator's
  URDF and the driver; body twist ↔ wheel rim speeds.
- :mod:`aes_ros.mona.framing`: COBS, CRC-16/CCITT-FALSE, frames and the streaming
  :class:`~aes_ros.mona.framing.FrameReader`, the protocol errors.
- :mod:`aes_ros.mona.messages`: the six message types and sequence counting.
- :mod:`aes_ros.mona.sensors`: raw IR and battery readings in SI units, wheel odometry.
"""
