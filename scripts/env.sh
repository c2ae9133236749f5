# Source this to use the project environment by hand: . scripts/env.sh
# It activates .venv and sets what ament_index and ROS 2 need, with network hygiene on:
# discovery stays on this host and the domain id is the project's own unless you set one.
_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
_venv=${BEV_MDO_VENV:-$_root/.venv}
. "$_venv/bin/activate"
export AMENT_PREFIX_PATH="$_venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export ROS_AUTOMATIC_DISCOVERY_RANGE=${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-77}
export RMW_IMPLEMENTATION=${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}
unset _root _venv
