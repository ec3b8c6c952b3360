# Source this file to use the workspace: the venv and catkin's devel space.
#   source scripts/env.sh
_cs_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$_cs_root/.venv/bin/activate"
# shellcheck disable=SC1091
source "$_cs_root/devel/setup.bash"
export ROS_HOME="${ROS_HOME:-$_cs_root/logs/ros}"
export PYTHONUNBUFFERED=1
unset _cs_root
