#!/usr/bin/env bash
# The many-core timings of issues 16 and 18 (README "On 16 cores"), run on
# the lent machine from the repository root after
# scripts/many_cores/prepare.sh. The lent machine's own speed moves by up
# to half between minutes, so every ratio is taken from adjacent runs:
# T7's walk and run on the top thread count and on 1 thread alternate in
# pairs; eight bodies and the fitted character are run three and two
# times; T7's walk on 2, 4 and 8 threads once each. With an "old" build
# beside it, the top-thread figures alternate old and new as A/B pairs.
# THREADS overrides the top thread count (default: every core); SMOKE=1
# runs every command on two frames, to check the script. Each command is
# stopped after LIMIT seconds (default 90): a hang costs one line, not the
# machine's lease.
set -uo pipefail
top="${THREADS:-$(nproc)}"
limit="${LIMIT:-90}"
T7=assets/scenes/t7.ron
FIT=assets/fitted/t7_makehuman/t7_makehuman.ron
builds=(new)
[ -x devrun/sinew_old ] && builds=(old new)
echo "$(nproc) cores: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
bench() {
    local build=$1
    shift
    if [ -n "${SMOKE:-}" ]; then
        local args=() skip=0
        for a in "$@"; do
            if [ "$skip" = 1 ]; then skip=0; continue; fi
            case "$a" in --from | --frames | --runs) skip=1 ;; *) args+=("$a") ;; esac
        done
        set -- "${args[@]}" --from 2 --frames 2 --runs 1
    fi
    echo "== $build: sinew bench $*"
    timeout "$limit" "devrun/sinew_$build" bench "$@" |
        grep -E '^(scene|read|integrate|update|closest|project|apply|write|blocks total|surface|ns per)' |
        cut -c1-170
    [ "${PIPESTATUS[0]}" = 124 ] && echo "!! stopped after $limit s"
}
for _ in 1 2 3; do
    for b in "${builds[@]}"; do
        bench "$b" "$T7" --from 120 --frames 60 --runs 1 --threads "$top"
    done
    bench new "$T7" --from 120 --frames 60 --runs 1 --threads 1
done
for _ in 1 2; do
    for b in "${builds[@]}"; do
        bench "$b" "$T7" --from 420 --frames 60 --runs 1 --threads "$top"
    done
    bench new "$T7" --from 420 --frames 60 --runs 1 --threads 1
done
for _ in 1 2 3; do
    for b in "${builds[@]}"; do
        bench "$b" "$T7" --instances 8 --from 120 --frames 30 --runs 1 --threads "$top"
    done
done
for _ in 1 2; do
    for b in "${builds[@]}"; do
        bench "$b" "$FIT" --from 120 --frames 40 --runs 1 --threads "$top"
    done
done
for t in 2 4 8; do
    [ "$t" -lt "$top" ] && bench new "$T7" --from 120 --frames 60 --runs 1 --threads "$t"
done
bench new "$FIT" --from 120 --frames 30 --runs 1 --threads 1
