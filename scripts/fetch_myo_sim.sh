#!/usr/bin/env bash
# Downloads the myo-sim musculoskeletal models (Apache-2.0) from PyPI and
# unpacks them under assets/mjcf/myo_sim/, where the MJCF wrappers in
# assets/mjcf/ include them from. Needs python3 with pip, or curl.
set -euo pipefail
cd "$(dirname "$0")/.."
VERSION="${MYO_SIM_VERSION:-0.2.4}"
DEST=assets/mjcf/myo_sim
if [ -f "$DEST/.version" ] && [ "$(cat "$DEST/.version")" = "$VERSION" ]; then
    echo "myo-sim $VERSION already in $DEST"
    exit 0
fi
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
if command -v pip >/dev/null 2>&1 || command -v pip3 >/dev/null 2>&1; then
    "$(command -v pip || command -v pip3)" download --no-deps --quiet "myo-sim==$VERSION" -d "$TMP"
else
    curl -sSfL -o "$TMP/myo_sim-$VERSION-py3-none-any.whl" \
        "https://files.pythonhosted.org/packages/py3/m/myo-sim/myo_sim-$VERSION-py3-none-any.whl"
fi
WHEEL="$(ls "$TMP"/myo_sim-*.whl)"
mkdir -p "$TMP/unpacked"
python3 -m zipfile -e "$WHEEL" "$TMP/unpacked"
rm -rf "$DEST"
mkdir -p "$DEST"
cp -r "$TMP/unpacked/myo_sim/models" "$DEST/models"
cp "$TMP"/unpacked/myo_sim-*.dist-info/licenses/LICENSE "$DEST/LICENSE"
echo "$VERSION" > "$DEST/.version"
echo "myo-sim $VERSION unpacked into $DEST"
