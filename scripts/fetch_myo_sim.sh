#!/usr/bin/env bash
# Downloads the myo-sim musculoskeletal models (Apache-2.0) from PyPI and
# unpacks them under assets/mjcf/myo_sim/, where the MJCF wrappers in
# assets/mjcf/ include them from. Needs python3 with pip, or curl.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/fetch_wheel.sh
VERSION="${MYO_SIM_VERSION:-0.2.4}"
DEST=assets/mjcf/myo_sim
if [ -f "$DEST/.version" ] && [ "$(cat "$DEST/.version")" = "$VERSION" ]; then
    echo "myo-sim $VERSION already in $DEST"
    exit 0
fi
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
fetch_wheel myo-sim "$VERSION" "$TMP"
rm -rf "$DEST"
mkdir -p "$DEST"
cp -r "$TMP/unpacked/myo_sim/models" "$DEST/models"
cp "$TMP"/unpacked/myo_sim-*.dist-info/licenses/LICENSE "$DEST/LICENSE"
echo "$VERSION" > "$DEST/.version"
echo "myo-sim $VERSION unpacked into $DEST"
