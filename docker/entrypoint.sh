#!/usr/bin/env bash
# Entry point of the CottonSim image: one `docker run` per job.
#   (no argument) | main      the main job (scripts/main.sh: the paper's GPS route)
#   test                      every test (scripts/test.sh)
#   reproduce <experiment>    an experiment of the paper (rosrun cottonsim_experiments reproduce --help)
#   anything else             run as a command inside the workspace environment
set -euo pipefail
cd /cottonsim
job="${1:-main}"
[ "$#" -gt 0 ] && shift
args=("$@")
set --     # catkin's setup script reads the positional parameters of whoever sources it
case "$job" in
  main) exec bash scripts/main.sh "${args[@]}" ;;
  test) exec bash scripts/test.sh "${args[@]}" ;;
  reproduce)
    # shellcheck disable=SC1091
    source scripts/env.sh
    exec rosrun cottonsim_experiments reproduce "${args[@]}" ;;
  *)
    # shellcheck disable=SC1091
    source scripts/env.sh
    exec "$job" "${args[@]}" ;;
esac
