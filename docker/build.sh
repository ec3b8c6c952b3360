#!/usr/bin/env bash
# Build the CottonSim image.
#   bash docker/build.sh                       # pip resolves torch==2.13.0 as configured (PyPI: the CUDA build)
#   bash docker/build.sh --wheels DIR          # offer the wheels in DIR first (e.g. torch-2.13.0+cpu-*.whl)
#   bash docker/build.sh --cpu-index           # torch from PyTorch's CPU index
#   bash docker/build.sh --tag NAME -- ARGS    # image name (default cottonsim); ARGS go to docker build
# Builds use the host's network (--network host): it works where Docker has no bridge.
# --wheels serves DIR over HTTP on the loopback for the build's dependency layer only, so
# the wheels never enter the image's layers or the build context.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
tag=cottonsim
wheels=""
build_args=()
while [ "$#" -gt 0 ]; do
  case "$1" in
    --wheels) wheels="${2:?--wheels needs a folder}"; shift 2 ;;
    --cpu-index) build_args+=(--build-arg PIP_EXTRA_INDEX_URL=https://download.pytorch.org/whl/cpu); shift ;;
    --tag) tag="${2:?--tag needs a name}"; shift 2 ;;
    --) shift; build_args+=("$@"); break ;;
    *) echo "docker/build.sh: unknown argument '$1' (see the header of this script)" >&2; exit 2 ;;
  esac
done
server_pid=""
cleanup() { [ -n "$server_pid" ] && kill "$server_pid" 2>/dev/null || true; }
trap cleanup EXIT
if [ -n "$wheels" ]; then
  [ -d "$wheels" ] || { echo "docker/build.sh: --wheels '$wheels' is not a folder" >&2; exit 2; }
  compgen -G "$wheels/*.whl" >/dev/null || { echo "docker/build.sh: no *.whl in '$wheels'" >&2; exit 2; }
  port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
  python3 -m http.server "$port" --bind 127.0.0.1 --directory "$wheels" >/dev/null 2>&1 &
  server_pid=$!
  for _ in $(seq 50); do python3 -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:$port/')" 2>/dev/null && break; sleep 0.1; done
  build_args+=(--build-arg "PIP_FIND_LINKS=http://127.0.0.1:$port/")
  echo "[build] offering the wheels of $wheels on http://127.0.0.1:$port/"
fi
cd "$ROOT"
start=$(date +%s)
docker build --network host -t "$tag" -f docker/Dockerfile "${build_args[@]}" .
echo "[build] $tag built in $(( $(date +%s) - start )) s; size: $(docker image inspect "$tag" --format '{{.Size}}' | awk '{printf "%.2f GB", $1/1e9}')"
