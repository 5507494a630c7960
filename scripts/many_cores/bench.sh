#!/usr/bin/env bash
# The many-core timings of issues 16 and 18 (README "On 16 cores"), run on
# the lent machine from the repository root after
# scripts/many_cores/prepare.sh: T7's walk on 1, 2, 4, 8 and 16 threads and
# its run on 1 and 16, eight bodies, and the fitted character; with an
# "old" build beside it, the 16-thread figures as interleaved A/B pairs.
# THREADS overrides the top thread count (default: every core); SMOKE=1
# runs every command on two frames, to check the script.
set -uo pipefail
top="${THREADS:-$(nproc)}"
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
    "devrun/sinew_$build" bench "$@" |
        grep -E '^(scene|read|integrate|update|closest|project|apply|write|blocks total|surface|ns per)' |
        cut -c1-170
}
for _ in 1 2; do
    for b in "${builds[@]}"; do
        bench "$b" "$T7" --from 120 --frames 60 --runs 3 --threads "$top"
    done
done
for b in "${builds[@]}"; do
    bench "$b" "$FIT" --from 120 --frames 60 --runs 2 --threads "$top"
done
for b in "${builds[@]}"; do
    bench "$b" "$T7" --instances 8 --from 120 --frames 30 --runs 2 --threads "$top" --method colored
done
# The crowd under Sequential too: ×0.92–0.96 of Colored on 16 threads.
bench new "$T7" --instances 8 --from 120 --frames 30 --runs 2 --threads "$top" --method sequential
bench new "$T7" --from 420 --frames 60 --runs 3 --threads "$top"
for t in 1 2 4 8; do
    [ "$t" -lt "$top" ] && bench new "$T7" --from 120 --frames 60 --runs 3 --threads "$t"
done
bench new "$T7" --from 420 --frames 60 --runs 2 --threads 1
bench new "$FIT" --from 120 --frames 30 --runs 1 --threads 1
