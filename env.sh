# source env.sh: this workspace in the current shell, for the ROS 2 command-line tools as for the project's own.
# After `make test` (or `make demo`): the venv's Python and tools, DDS on loopback in a domain of your choice (with
# the project's Fast DDS profile), and the ament index of the workspace's packages (colcon's install/) and of the
# interfaces built into the venv, which is what `ros2 pkg list`, `ros2 run`, `ros2 interface show` and
# `ros2 topic echo` look things up in.
_here="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")" && pwd)"
if [ ! -x "$_here/.venv/bin/python" ]; then
    echo "env.sh: no .venv in $_here yet: run 'make test' (or 'make demo') first" >&2
    return 1 2>/dev/null || exit 1
fi
. "$_here/.venv/bin/activate"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-42}"
# The project's Fast DDS profile (quick discovery: docs/deployment.md), unless a profile or middleware is chosen.
if [ -z "${FASTRTPS_DEFAULT_PROFILES_FILE:-}${FASTDDS_DEFAULT_PROFILES_FILE:-}" ] && \
   case "${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}" in rmw_fastrtps*) true ;; *) false ;; esac; then
    export FASTRTPS_DEFAULT_PROFILES_FILE="$_here/src/picking_common/picking_common/fastdds.xml"
fi
if [ -f "$_here/install/setup.bash" ] && [ -n "$BASH_VERSION" ]; then
    . "$_here/install/setup.bash"
fi
case ":${AMENT_PREFIX_PATH:-}:" in
    *":$_here/.venv:"*) ;;
    *) export AMENT_PREFIX_PATH="$_here/.venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}" ;;
esac
unset _here
