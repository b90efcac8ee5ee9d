#!/usr/bin/env bash
# Start an AES swarm by hand from the console scripts, as `aes-swarm launch` does:
# the pybullet bridge, the supervisor and the robot hosts, each its own process.
# Ctrl-C (or SIGTERM) stops all of them cleanly. (Started with `&` from another
# script, bash ignores SIGINT for it: stop it with `kill -TERM` then.)
#
#   scripts/start_swarm.sh                     # 16 robots, combined setup, one robot host
#   scripts/start_swarm.sh -s linear -n 36 -k 1
#   scripts/start_swarm.sh -s my_scenario.yaml -x odom -m dynamic -g
#   scripts/start_swarm.sh -n 400 -d server     # through a Fast DDS discovery server
#
# Options:
#   -s SETUP   linear | rotation | combined (default) or a scenario YAML file
#   -n N       number of robots (default 16; 0 = the scenario's formation)
#   -k K       number of robot host processes (default: as `aes-swarm launch`'s layout
#              auto: one up to 20000 robot-steps/s and on <= 2 cores, else one per core)
#   -x SOURCE  neighbour source: poses (default) | odom
#   -m MODE    kinematic (default) | dynamic
#   -r X       real-time factor (default 1; 0 = as fast as possible)
#   -e SEED    seed of the initial state (default 0)
#   -g         pybullet GUI
#   -d MODE    discovery: auto (default: a server above the robot count of
#              `aes-swarm launch --discovery auto`, or with -a) | simple | server
#              (starts fast-discovery-server first, on a free UDP port, and points every
#              process at it; prints the lines a shell needs for ros2 commands)
#   -a H:P     use this running discovery server (id 0, e.g. on another host)
#
# While it runs, in another shell (same ROS_DOMAIN_ID; with a discovery server, the
# lines it printed first):
#   scripts/steer.sh north               # or: aes-swarm steer --direction 0 1
#   ros2 topic echo /swarm/alignment     # with a full ROS 2 install
#   ros2 param set /supervisor rotation_rate 0.5
set -euo pipefail

SETUP=combined ROBOTS=16 HOSTS=auto SOURCE=poses MODE=kinematic
RTF=1.0 SEED=0 GUI=false DISCOVERY=auto SERVER=""
while getopts "s:n:k:x:m:r:e:d:a:gh" opt; do
    case $opt in
        s) SETUP=$OPTARG ;;
        n) ROBOTS=$OPTARG ;;
        k) HOSTS=$OPTARG ;;
        x) SOURCE=$OPTARG ;;
        m) MODE=$OPTARG ;;
        r) RTF=$OPTARG ;;
        e) SEED=$OPTARG ;;
        g) GUI=true ;;
        d) DISCOVERY=$OPTARG ;;
        a) SERVER=$OPTARG ;;
        h) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
        *) echo "usage: $0 [-s setup|file] [-n robots] [-k hosts] [-x poses|odom]" \
                "[-m kinematic|dynamic] [-r rtf] [-e seed] [-g] [-d auto|simple|server]" \
                "[-a host:port]" >&2; exit 2 ;;
    esac
done
case $ROBOTS in ''|*[!0-9]*) echo "$0: -n: need a whole number, got '$ROBOTS'" >&2; exit 2 ;; esac
case $HOSTS in auto) ;; ''|*[!0-9]*|0) echo "$0: -k: need a whole number >= 1, got '$HOSTS'" >&2; exit 2 ;; esac
case $SOURCE in poses|odom) ;; *) echo "$0: -x: poses or odom, got '$SOURCE'" >&2; exit 2 ;; esac
case $MODE in kinematic|dynamic) ;; *) echo "$0: -m: kinematic or dynamic, got '$MODE'" >&2; exit 2 ;; esac
case $RTF in *[!0-9.]*|'') echo "$0: -r: need a number >= 0, got '$RTF'" >&2; exit 2 ;; esac
case $RTF in *.*) ;; *) RTF=$RTF.0 ;; esac  # a ROS double needs a decimal point
case $SEED in ''|*[!0-9]*) echo "$0: -e: need a whole number >= 0, got '$SEED'" >&2; exit 2 ;; esac
case $DISCOVERY in auto|simple|server) ;; *) echo "$0: -d: auto, simple or server, got '$DISCOVERY'" >&2; exit 2 ;; esac
if [ -n "$SERVER" ] && [ "$DISCOVERY" = simple ]; then
    echo "$0: -a: simple discovery uses no server" >&2; exit 2
fi

# Console scripts of the environment this script's aes-swarm lives in, else PATH.
BIN=${AES_BIN:-$(dirname "$(command -v aes-sim-bridge || echo ./aes-sim-bridge)")}
if [ ! -x "$BIN/aes-sim-bridge" ]; then
    echo "$0: aes-sim-bridge not found; activate the environment (pip install -e .)" >&2
    exit 1
fi

# The Fast DDS profile aes-swarm launch uses (participants announce themselves every
# 0.5 s, so a restarted process finds the others quickly), unless one is set.
if [ -z "${FASTRTPS_DEFAULT_PROFILES_FILE:-}${FASTDDS_DEFAULT_PROFILES_FILE:-}" ]; then
    FASTRTPS_DEFAULT_PROFILES_FILE=$("$BIN/python" -c \
        "from aes_ros.ros.launch.processes import FASTDDS_PROFILE; print(FASTDDS_PROFILE)")
    export FASTRTPS_DEFAULT_PROFILES_FILE
fi

# The robot count as the scenario sees it (0 = the scenario's own formation) and the
# layout auto of launch (aes_ros.ros.launch.layout.auto_layout). Every user value reaches
# Python as an argument (sys.argv), never as part of its code.
SCENARIO_INFO='
import sys
from aes_ros import scenario
from aes_ros.params import ParameterError
from aes_ros.ros.launch.layout import auto_layout
setup, robots = sys.argv[1], int(sys.argv[2])
try:
    sc = scenario.load(setup)
except ParameterError as exc:
    sys.exit(f"{sys.argv[3]}: -s: {exc}")
robots = robots or len(sc.nominal_positions())
print(robots, auto_layout(robots, sc.dt))
'
INFO=$("$BIN/python" -c "$SCENARIO_INFO" "$SETUP" "$ROBOTS" "$0") || exit 2
NUM=$ROBOTS
read -r ROBOTS LAYOUT <<<"$INFO"
if [ "$HOSTS" = auto ]; then
    HOSTS=1
    [ "$LAYOUT" = single ] || HOSTS=$(nproc 2>/dev/null || echo 1)
fi
[ "$HOSTS" -le "$ROBOTS" ] || HOSTS=$ROBOTS

# Discovery as `aes-swarm launch --discovery` decides it (aes_ros.ros.discovery).
if [ -n "$SERVER" ]; then
    "$BIN/python" -c "import sys; from aes_ros.ros.discovery import parse_address; \
parse_address(sys.argv[1])" "$SERVER" 2>/dev/null \
        || { echo "$0: -a: expected HOST:PORT, got '$SERVER'" >&2; exit 2; }
fi
DISCOVERY=$("$BIN/python" -c "import sys; from aes_ros.ros.discovery import resolved_mode; \
print(resolved_mode(sys.argv[1], int(sys.argv[2]), sys.argv[3] or None))" \
    "$DISCOVERY" "$ROBOTS" "$SERVER")
if [ -n "${ROS_DISCOVERY_SERVER:-}" ] && [ "$ROS_DISCOVERY_SERVER" != "$SERVER" ]; then
    echo "note: ROS_DISCOVERY_SERVER=$ROS_DISCOVERY_SERVER of the environment is not used" \
        "(-a $ROS_DISCOVERY_SERVER would use that server)"
fi
unset ROS_DISCOVERY_SERVER ROS_SUPER_CLIENT

set -m  # each background job in its own process group: Ctrl-C reaches only this script
PIDS=() SERVER_PID=""
start() {  # name, command...
    local name=$1; shift
    echo "starting $name: $*"
    "$@" &
    PIDS+=($!)
}

stop_all() {
    trap - INT TERM
    echo "stopping ${#PIDS[@]} processes"
    # The discovery server last: the others' goodbyes go through it.
    for pid in "${PIDS[@]}"; do
        [ "$pid" = "$SERVER_PID" ] || kill -INT "$pid" 2>/dev/null || true
    done
    for _ in $(seq 100); do  # up to 10 s for a clean shutdown
        alive=0
        for pid in "${PIDS[@]}"; do
            [ "$pid" = "$SERVER_PID" ] || { kill -0 "$pid" 2>/dev/null && alive=1; }
        done
        [ $alive -eq 0 ] && break
        sleep 0.1
    done
    [ -z "$SERVER_PID" ] || kill -INT "$SERVER_PID" 2>/dev/null || true
    for _ in $(seq 20); do
        { [ -z "$SERVER_PID" ] || ! kill -0 "$SERVER_PID" 2>/dev/null; } && break
        sleep 0.1
    done
    for pid in "${PIDS[@]}"; do
        if kill -0 "$pid" 2>/dev/null; then
            echo "killing $pid"
            kill -KILL -- "-$pid" 2>/dev/null || kill -KILL "$pid" 2>/dev/null || true
        fi
    done
    wait 2>/dev/null || true
    # Fast DDS leaves shared-memory files behind for killed processes; this removes only
    # this user's files that no live participant holds (not `fastdds shm clean`, which
    # removes any user's).
    "$BIN/python" -c "import sys; from aes_ros.ros.launch.shared_memory import \
clean_shared_memory; clean_shared_memory(int(sys.argv[1]))" "${ROS_DOMAIN_ID:-0}" || true
}
trap 'stop_all; exit 0' INT TERM

if [ "$DISCOVERY" = server ]; then
    ENV_ARGS=()
    if [ -z "$SERVER" ]; then  # our own, first: on loopback when discovery stays on this host
        LISTEN=$("$BIN/python" -m aes_ros.ros.discovery listen)  # else on one interface
        PORT=$("$BIN/python" -m aes_ros.ros.discovery port --listen "$LISTEN")
        SERVER=$LISTEN:$PORT
        ENV_ARGS=(--listen "$LISTEN")
        start discovery_server "$BIN/python" -m aes_ros.ros.discovery serve --port "$PORT" \
            --listen "$LISTEN"
        SERVER_PID=${PIDS[-1]}
    fi
    export ROS_DISCOVERY_SERVER=$SERVER  # every process below is a client of it
    echo "discovery server $SERVER; ros2 commands on this swarm need:"
    "$BIN/python" -m aes_ros.ros.discovery env "$SERVER" "${ENV_ARGS[@]}" | sed 's/^/  /'
fi

COMMON=(-p "scenario:=$SETUP" -p "num_robots:=$NUM")
start sim_bridge "$BIN/aes-sim-bridge" --ros-args "${COMMON[@]}" -p "seed:=$SEED" \
    -p "mode:=$MODE" -p "real_time_factor:=$RTF" -p "gui:=$GUI"
start supervisor "$BIN/aes-supervisor" --ros-args "${COMMON[@]}" -p use_sim_time:=true
for ((h = 0; h < HOSTS; h++)); do
    first=$((h * ROBOTS / HOSTS)) end=$(((h + 1) * ROBOTS / HOSTS))
    ids=$(seq -s, "$first" $((end - 1)))
    start "robot_host_$h (robots $first..$((end - 1)))" "$BIN/aes-robot-host" --ros-args \
        -r "robot_host:__node:=robot_host_$h" "${COMMON[@]}" -p use_sim_time:=true \
        -p "neighbor_source:=$SOURCE" -p "robot_ids:=[$ids]"
done
echo "swarm running (ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-0}); Ctrl-C stops it"

# Run until Ctrl-C, or until one process ends by itself (then stop the rest too).
set +e
wait -n
echo "a process exited; stopping the swarm" >&2
stop_all
exit 1
