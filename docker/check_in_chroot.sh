#!/usr/bin/env bash
# Check the Docker recipe where no Docker engine runs: the Dockerfile's steps in
# a fresh Debian 12 (bookworm) chroot made by debootstrap, the repository as a
# clean archive of HEAD (what a fresh clone holds), then one job of the image's
# entry point. Needs root, debootstrap (installed if missing) and network access
# to Debian's mirror and PyPI.
#
#   sudo docker/check_in_chroot.sh                       # set up, then the main job
#   sudo docker/check_in_chroot.sh reproduce --help      # any entry-point job
#   sudo CHROOT_DIR=/tmp/cs_chroot docker/check_in_chroot.sh test -x
#
# CHROOT_DIR (default /tmp/cottonsim_bookworm) is kept between runs: a second
# run reuses the Debian base and re-copies the repository. What differs from a
# `docker run`: the chroot shares the host's kernel, network and /dev; the
# host's CA bundle and /etc/hosts are copied in (a TLS-intercepting proxy, as on
# our development machines, needs its CA); a host folder of wheels (/opt/wheels,
# e.g. the CPU build of torch) is offered to pip the way the Dockerfile's
# PIP_EXTRA_INDEX_URL build argument offers an index.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CHROOT_DIR="${CHROOT_DIR:-/tmp/cottonsim_bookworm}"
MIRROR="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"
[ "$(id -u)" = "0" ] || { echo "check_in_chroot: run as root (chroot, mount)" >&2; exit 2; }
[ "$#" -gt 0 ] || set -- main

# The packages the Dockerfile installs before scripts/setup.sh, read from it so the two cannot drift.
# (continuation lines joined; the words between "--no-install-recommends" and the next "&&")
base_packages="$(sed -e ':a' -e '/\\$/N; s/\\\n//; ta' "$ROOT/docker/Dockerfile" \
  | sed -n 's/.*apt-get install [^&]*--no-install-recommends\([^&]*\)&&.*/\1/p' | tr -s ' ' ' ')"
[ -n "$base_packages" ] || { echo "check_in_chroot: no apt-get install line in docker/Dockerfile" >&2; exit 2; }

if [ ! -x "$CHROOT_DIR/usr/bin/apt-get" ]; then
  command -v debootstrap >/dev/null || apt-get install -y -qq debootstrap >/dev/null
  echo "[chroot] debootstrap bookworm -> $CHROOT_DIR"
  debootstrap --variant=minbase bookworm "$CHROOT_DIR" "$MIRROR" >/dev/null
fi
cp /etc/resolv.conf "$CHROOT_DIR/etc/resolv.conf"
printf '127.0.0.1\tlocalhost\n::1\tlocalhost ip6-localhost ip6-loopback\n127.0.1.1\t%s\n' "$(hostname)" \
  > "$CHROOT_DIR/etc/hosts"

mounts=()
cleanup() { for ((i = ${#mounts[@]} - 1; i >= 0; i--)); do umount -R "${mounts[$i]}" 2>/dev/null || true; done; }
trap cleanup EXIT
mount -t proc proc "$CHROOT_DIR/proc" && mounts+=("$CHROOT_DIR/proc")
mount --rbind /dev "$CHROOT_DIR/dev" && mounts+=("$CHROOT_DIR/dev")
mount --rbind /sys "$CHROOT_DIR/sys" && mounts+=("$CHROOT_DIR/sys")
pip_env=""
if [ -d /opt/wheels ]; then
  mkdir -p "$CHROOT_DIR/opt/wheels"
  mount --bind /opt/wheels "$CHROOT_DIR/opt/wheels" && mounts+=("$CHROOT_DIR/opt/wheels")
  pip_env="PIP_FIND_LINKS=/opt/wheels"
fi

echo "[chroot] the Dockerfile's base packages: $base_packages"
# shellcheck disable=SC2086
chroot "$CHROOT_DIR" bash -c "apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
  apt-get install -y -qq --no-install-recommends $base_packages >/dev/null"
# after ca-certificates: the host's bundle (it holds a proxy's CA where there is one)
cp /etc/ssl/certs/ca-certificates.crt "$CHROOT_DIR/etc/ssl/certs/ca-certificates.crt"

echo "[chroot] repository: git archive HEAD -> /cottonsim"
rm -rf "$CHROOT_DIR/cottonsim" && mkdir -p "$CHROOT_DIR/cottonsim"
git -C "$ROOT" archive HEAD | tar -x -C "$CHROOT_DIR/cottonsim"

start=$(date +%s)
chroot "$CHROOT_DIR" env $pip_env bash -c "cd /cottonsim && bash scripts/setup.sh"
echo "[chroot] scripts/setup.sh passed in $(( $(date +%s) - start )) s"
start=$(date +%s)
status=0
chroot "$CHROOT_DIR" bash -c "cd /cottonsim && bash docker/entrypoint.sh $(printf '%q ' "$@")" || status=$?
echo "[chroot] docker/entrypoint.sh $* exited $status after $(( $(date +%s) - start )) s"
exit "$status"
