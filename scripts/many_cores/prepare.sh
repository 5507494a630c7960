#!/usr/bin/env bash
# Prepares a many-core timing run on a machine without Rust: builds the
# release `sinew` here (optionally also the build of another commit, for an
# A/B pair), strips it into `devrun/` (ignored through .git/info/exclude)
# with `scripts/many_cores/bench.sh`, and makes sure the fitted scene the
# character's figures need exists. Carry `devrun`,
# `assets/fitted/t7_makehuman/t7_makehuman.ron` and
# `assets/fitted/t7_makehuman/meshes` to the other machine (not the whole
# `assets/fitted`: other fitted scenes there can push the copy past the
# device tool's 64 MiB) and run `bash devrun/bench.sh` there from the
# repository root (it needs only bash, coreutils and the assets the
# repository tracks). The whole script takes about 3 minutes on 16 cores (4 with an old build).
#
#   scripts/many_cores/prepare.sh            # the working tree's build
#   scripts/many_cores/prepare.sh c499185    # and that commit's, as "old"
set -euo pipefail
cd "$(dirname "$0")/../.."
mkdir -p .git/info devrun
grep -qx 'devrun/' .git/info/exclude 2>/dev/null || echo 'devrun/' >> .git/info/exclude
cargo build --release -p sinew_cli
cp target/release/sinew devrun/sinew_new
strip devrun/sinew_new
rm -f devrun/sinew_old
if [ $# -ge 1 ]; then
    old="$(mktemp -d)"
    trap 'git worktree remove --force "$old" >/dev/null 2>&1 || true' EXIT
    git worktree add --detach "$old" "$1" >/dev/null
    CARGO_TARGET_DIR=target/many_cores_old cargo build --release -p sinew_cli --manifest-path "$old/Cargo.toml"
    cp target/many_cores_old/release/sinew devrun/sinew_old
    strip devrun/sinew_old
fi
cp scripts/many_cores/bench.sh devrun/bench.sh
if [ ! -f assets/fitted/t7_makehuman/t7_makehuman.ron ]; then
    cargo run --release -p sinew_cli -- fit assets/characters/makehuman.glb assets/scenes/t7.ron \
        --out assets/fitted/t7_makehuman/t7_makehuman.ron
fi
du -sh devrun assets/fitted
