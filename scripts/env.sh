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
# rospy advertises this machine's host name unless ROS_HOSTNAME or ROS_IP is set; where that name
# does not resolve (common on cloud VMs and in containers) every node would die with
# "socket.gaierror: Name or service not known". Keep ROS on the loopback then, and say so.
if [ -z "${ROS_HOSTNAME:-}" ] && [ -z "${ROS_IP:-}" ] && ! getent hosts "$(hostname)" >/dev/null 2>&1; then
  export ROS_HOSTNAME=localhost
  echo "[env] this machine's host name '$(hostname)' does not resolve: ROS_HOSTNAME=localhost (set ROS_HOSTNAME or ROS_IP to reach other machines)" >&2
fi
unset _cs_root _cs_nounset
