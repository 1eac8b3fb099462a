#!/usr/bin/env bash
# fetch-portrait.sh DEST_DIR: puts the public-domain portrait astronaut.png (shipped in
# Debian's python3-skimage) into DEST_DIR, without installing the package or Python.
set -euo pipefail

if [[ $# -ne 1 ]]; then
  echo "usage: $0 DEST_DIR" >&2
  exit 2
fi
dest=$1
[[ -f "$dest/astronaut.png" ]] && exit 0

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# As root, apt warns that the _apt sandbox user cannot write here; the download still works.
(cd "$work" && apt-get download -qq python3-skimage 2>&1 | grep -v "_apt" >&2 || true)
shopt -s nullglob
debs=("$work"/python3-skimage_*.deb)
if [[ ${#debs[@]} -eq 0 ]]; then
  echo "$0: could not download python3-skimage (is apt configured and the network up?)" >&2
  exit 1
fi
dpkg-deb -x "${debs[0]}" "$work/root"
portrait="$work/root/usr/lib/python3/dist-packages/skimage/data/astronaut.png"
if [[ ! -f "$portrait" ]]; then
  echo "$0: ${debs[0]##*/} holds no skimage/data/astronaut.png" >&2
  exit 1
fi
mkdir -p "$dest"
# Copy then rename: a parallel build never sees a half-written portrait.
cp "$portrait" "$dest/astronaut.png.tmp$$"
mv "$dest/astronaut.png.tmp$$" "$dest/astronaut.png"
