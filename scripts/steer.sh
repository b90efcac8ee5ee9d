#!/usr/bin/env bash
# Steer a running swarm (started by scripts/start_swarm.sh or `aes-swarm launch`).
#
#   scripts/steer.sh north | south | east | west   # drive that way, keep the rotation
#   scripts/steer.sh ccw | cw                      # rotate at +/-0.5 rad/s, keep the drive
#   scripts/steer.sh still                         # no drive, no rotation
#   scripts/steer.sh off | on                      # /swarm/enable: stop / restart every robot
#   scripts/steer.sh X Y W                         # direction (X, Y), rotation rate W [rad/s]
#
# Equivalent commands with a full ROS 2 install:
#   ros2 topic pub --once /swarm/cmd geometry_msgs/msg/Twist "{linear: {x: 0.0, y: 1.0}}"
#   ros2 service call /swarm/enable std_srvs/srv/SetBool "{data: false}"
#   ros2 param set /supervisor rotation_rate 0.5
#   ros2 topic echo /swarm/alignment
set -euo pipefail

BIN=$(dirname "$(command -v aes-swarm || echo ./aes-swarm)")
PY=${BIN}/python
[ -x "$PY" ] || PY=python3

case ${1:-} in
    north) exec "$BIN/aes-swarm" steer --direction 0 1 ;;
    south) exec "$BIN/aes-swarm" steer --direction 0 -1 ;;
    east) exec "$BIN/aes-swarm" steer --direction 1 0 ;;
    west) exec "$BIN/aes-swarm" steer --direction -1 0 ;;
    ccw) exec "$BIN/aes-swarm" steer --omega 0.5 ;;
    cw) exec "$BIN/aes-swarm" steer --omega -0.5 ;;
    still) exec "$BIN/aes-swarm" steer --direction 0 0 --omega 0 ;;
    on | off)
        # /swarm/enable (std_srvs/SetBool) with rclpy, as `ros2 service call` would.
        exec "$PY" - "$1" <<'EOF'
import sys

import rclpy
from std_srvs.srv import SetBool

rclpy.init()
node = rclpy.create_node("aes_enable")
client = node.create_client(SetBool, "/swarm/enable")
if not client.wait_for_service(timeout_sec=15.0):
    sys.exit("steer.sh: no /swarm/enable service (is the swarm running in this ROS_DOMAIN_ID?)")
future = client.call_async(SetBool.Request(data=sys.argv[1] == "on"))
rclpy.spin_until_future_complete(node, future, timeout_sec=15.0)
result = future.result()
print(f"/swarm/enable {sys.argv[1]}: {result.message if result else 'no answer'}")
node.destroy_node()
rclpy.try_shutdown()
sys.exit(0 if result is not None and result.success else 1)
EOF
        ;;
    *)
        if [ $# -eq 3 ]; then
            exec "$BIN/aes-swarm" steer --direction "$1" "$2" --omega "$3"
        fi
        sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
        exit 2
        ;;
esac
