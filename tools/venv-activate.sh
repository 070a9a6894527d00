
# cdpr environment: what rclpy from PyPI wheels needs, and the shipped DDS set-up (UDP on
# loopback only, no shared memory; src/cdpr_msgs_py/cdpr_msgs_py/dds.py) unless a Fast DDS
# profile of your own is set.
export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
if [ -z "${FASTDDS_DEFAULT_PROFILES_FILE+set}" ]; then
    export FASTDDS_DEFAULT_PROFILES_FILE="$(dirname "$VIRTUAL_ENV")/src/cdpr_msgs_py/cdpr_msgs_py/fastdds_loopback.xml"
    export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET
fi
