# Source this file to use the workspace: the venv and catkin's devel space.
#   source scripts/env.sh
# Safe under `set -u`: catkin's profile scripts read unset variables.
_cs_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
case "$-" in *u*) _cs_nounset=1; set +u ;; *) _cs_nounset=0 ;; esac
# shellcheck disable=SC1091
source "$_cs_root/.venv/bin/activate"
# shellcheck disable=SC1091
source "$_cs_root/devel/setup.bash"
[ "$_cs_nounset" = 1 ] && set -u
export ROS_HOME="${ROS_HOME:-$_cs_root/logs/ros}"
export PYTHONUNBUFFERED=1
unset _cs_root _cs_nounset
