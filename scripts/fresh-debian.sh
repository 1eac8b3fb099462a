#!/usr/bin/env bash
# The quick start on a fresh Debian 12: a minimal bookworm root (debootstrap), this checkout
# cloned into it, then `./scripts/dev.sh test` (or the command given) inside it under chroot,
# with nothing installed but what the project's own scripts install. Not part of CI: it needs
# root and the network, and takes about 25 minutes (the packages, a cold build, the suite).
# Usage: sudo scripts/fresh-debian.sh [root dir] [command...]
#   (default /var/tmp/lipdrive-fresh, ./scripts/dev.sh test; the root is made once and kept,
#   so a second run takes the checkout's new commits and builds on what it built)
set -euo pipefail
cd "$(dirname "$0")/.."
root=${1:-/var/tmp/lipdrive-fresh}
shift || true
[ $# -eq 0 ] && set -- ./scripts/dev.sh test

./scripts/install-deps.sh debootstrap git
[ -x "$root/bin/bash" ] || debootstrap --variant=minbase bookworm "$root" http://deb.debian.org/debian
cp /etc/resolv.conf "$root/etc/resolv.conf"
for m in proc sys dev dev/pts dev/shm; do
  mountpoint -q "$root/$m" || mount --bind "/$m" "$root/$m"
done
trap 'for m in dev/shm dev/pts dev sys proc; do umount "$root/$m" 2>/dev/null || true; done' EXIT

# The checkout's commits, not its uncommitted changes; ../shared stays out (tests skip).
src=/root/src/lipdrive
if [ -d "$root$src/.git" ]; then
  git -C "$root$src" pull -q --ff-only "$PWD" HEAD
else
  mkdir -p "$root/root/src" && git clone -q "$PWD" "$root$src"
fi
chroot "$root" /usr/bin/env -i HOME=/root LANG=C.UTF-8 PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
  /bin/bash -c 'cd "$0" && exec "$@"' "$src" "$@"
