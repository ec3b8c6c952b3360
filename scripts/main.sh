#!/usr/bin/env bash
# Set everything up (idempotent, see scripts/setup.sh), then run the main job:
# the paper's GPS-based experiment, headless and as fast as the machine allows:
# the robot drives the 30-waypoint serpentine GPS route through the default
# cotton farm (navsat transform + move_base with navfn and DWA), with Cotton-Eye
# in the loop (cameras, segmentation + row centring -> move_base, halts at bolls;
# vision:=false = LiDAR + GPS alone, several times faster); at the end
# results/gps_route/ (under $COTTONSIM_RESULTS when set) holds report.json (the
# paper's CR, AE, RMSE, plant contacts, cross-track error, durations) and
# trajectory.png (planned vs actual, as the paper's Fig. 14a).
#   bash scripts/main.sh                                  # default run
#   bash scripts/main.sh run_name:=mine record_bag:=true  # extra roslaunch arguments
#   bash scripts/main.sh vision:=false                    # the LiDAR + GPS run
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
run_name="gps_route"
results="${COTTONSIM_RESULTS:-$ROOT/results}"
for arg in "$@"; do
  case "$arg" in run_name:=*) run_name="${arg#run_name:=}" ;; esac
done
roslaunch cottonsim_experiments gps_navigation.launch run_name:="$run_name" results_dir:="$results" "$@"
report="$results/$run_name/report.json"
if [ -f "$report" ]; then
  echo "[main] report: $report"
  cat "$report"
  echo "[main] figure: $results/$run_name/trajectory.png"
else
  echo "[main] no report was written (see the log above)"; exit 1
fi
