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

case ${1:-} in
    north) exec "$BIN/aes-swarm" steer --direction 0 1 ;;
    south) exec "$BIN/aes-swarm" steer --direction 0 -1 ;;
    east) exec "$BIN/aes-swarm" steer --direction 1 0 ;;
    west) exec "$BIN/aes-swarm" steer --direction -1 0 ;;
    ccw) exec "$BIN/aes-swarm" steer --omega 0.5 ;;
    cw) exec "$BIN/aes-swarm" steer --omega -0.5 ;;
    still) exec "$BIN/aes-swarm" steer --direction 0 0 --omega 0 ;;
    on) exec "$BIN/aes-swarm" steer --enable ;;
    off) exec "$BIN/aes-swarm" steer --disable ;;
    *)
        if [ $# -eq 3 ]; then
            exec "$BIN/aes-swarm" steer --direction "$1" "$2" --omega "$3"
        fi
        sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
        exit 2
        ;;
esac
