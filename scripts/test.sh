#!/usr/bin/env bash
# Set everything up (idempotent, see scripts/setup.sh), then run every test:
# unit tests of the pure cores (no ROS master), the rostests of each node and
# the whole-system scenarios in tests/. One pytest run drives them all, so the
# closing line counts every test; a failure anywhere fails the command.
#   bash scripts/test.sh            # everything
#   bash scripts/test.sh -k camera  # extra arguments go to pytest
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/setup.sh
# shellcheck disable=SC1091
source scripts/env.sh
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-2}"
python -m pytest "$@"
