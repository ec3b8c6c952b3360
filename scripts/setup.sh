#!/usr/bin/env bash
# Set up everything CottonSim needs on a fresh Debian 12 (bookworm) machine.
# Idempotent: safe to run again; each step only does work that is missing.
#   1. Debian's ROS 1 packages (apt, needs root or sudo)
#   2. a venv at .venv from /usr/bin/python3 with --system-site-packages
#   3. the pinned pip packages of requirements.txt
#   4. catkin_make of the workspace (devel/ and build/)
#   bash scripts/setup.sh               # all four steps
#   bash scripts/setup.sh --deps-only   # steps 1-3 (the Docker image caches them in their own layer)
set -euo pipefail
deps_only=0
case "${1:-}" in
  "") ;;
  --deps-only) deps_only=1 ;;
  *) echo "[setup] unknown argument '$1' (the only option is --deps-only)" >&2; exit 2 ;;
esac
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

APT_PACKAGES=(
  # catkin_make's toolchain: a bare debian:bookworm has no make or C/C++ compiler
  cmake make g++
  catkin ros-message-generation ros-message-runtime
  ros-std-msgs ros-geometry-msgs ros-sensor-msgs ros-nav-msgs
  libstd-msgs-dev libgeometry-msgs-dev libsensor-msgs-dev libnav-msgs-dev
  librostest-dev libactionlib-msgs-dev ros-actionlib-msgs
  python3-rospy python3-roslaunch python3-rostest python3-rosbag
  python3-rostopic python3-rosservice python3-rosnode python3-rosmsg rosbash
  python3-tf2-ros python3-tf2-geometry-msgs python3-message-filters
  python3-actionlib python3-std-msgs python3-geometry-msgs python3-sensor-msgs
  python3-nav-msgs python3-move-base-msgs python3-actionlib-msgs
  python3-tf2-msgs python3-visualization-msgs python3-map-msgs
  ros-robot-state-publisher joint-state-publisher rviz python3-pyode python3-venv
  python3-trajectory-msgs python3-rosgraph-msgs python3-matplotlib python3-rospkg
  python3-std-srvs ros-std-srvs
  ros-trajectory-msgs libtrajectory-msgs-dev
  xvfb imagemagick
)

SUDO=""
if [ "$(id -u)" != "0" ]; then SUDO="sudo"; fi

missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  echo "[setup] apt: installing ${#missing[@]} packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  echo "[setup] apt: all ${#APT_PACKAGES[@]} packages present"
fi

if [ ! -x .venv/bin/python ]; then
  echo "[setup] venv: creating .venv from /usr/bin/python3"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
stamp=.venv/.requirements.sha
want="$(sha256sum requirements.txt | cut -d' ' -f1)"
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "[setup] pip: installing requirements.txt"
  extra=()
  [ -d /opt/wheels ] && extra+=(--find-links /opt/wheels)
  # (the grep drops pip's notes about extra index folders this machine's pip config names)
  { .venv/bin/pip install -q --disable-pip-version-check "${extra[@]}" -r requirements.txt 2>&1; } \
    | { grep -v "is ignored: it is neither a file nor a directory" || true; }
  echo "$want" > "$stamp"
else
  echo "[setup] pip: requirements up to date"
fi

if [ "$deps_only" = 1 ]; then
  echo "[setup] done: dependencies only (--deps-only), no catkin_make"
  exit 0
fi

echo "[setup] catkin_make"
# PYTHON_EXECUTABLE: the venv's python, so generated scripts and tests see its packages.
# --force-cmake every time: it is cheap, the packages glob nodes/ and scripts/ at
# configure time (new executables need a re-configure), and catkin caches an empty
# PYTHONPATH at a fresh tree's first configure.
force=(--force-cmake)
catkin_make -DPYTHON_EXECUTABLE="$ROOT/.venv/bin/python" -DCMAKE_BUILD_TYPE=Release \
  -DCATKIN_ENABLE_TESTING=ON "${force[@]}" >logs_catkin.txt 2>&1 || {
    cat logs_catkin.txt; echo "[setup] catkin_make failed"; exit 1; }
mkdir -p logs && mv logs_catkin.txt logs/catkin_make.txt
echo "[setup] done: source scripts/env.sh to use the workspace"
