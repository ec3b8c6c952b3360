#!/usr/bin/env bash
# Set everything up (idempotent, see scripts/setup.sh), then run the main job:
# the robot drives the paper's serpentine route through the default cotton farm,
# headless, on the simulator bridge; results land in results/<run>/.
#   bash scripts/main.sh                 # default run
#   bash scripts/main.sh run:=demo       # extra roslaunch arguments
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
exec roslaunch --screen cottonsim_world drive_route.launch results_dir:="$ROOT/results" "$@"
