"""``aes-mona-driver``: real Monas on ROS 2 over the Mona link v1 (docs/mona_protocol.md)."""
