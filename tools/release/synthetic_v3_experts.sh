#!/usr/bin/env bash
# Trains the seven snippet experts behind synthetic-v3 again, with its card's recipe (--profile fast-3m-wide, one
# seed): two lanes side by side on a 2-core machine, about 2 hours per pair of 3M-step experts. Resumable: rerun it
# after a kill and every expert continues from its checkpoint; finished ones are skipped.
# Then, per expert: python tools/release/expert_card.py RUN --out CARD.json and mocap-hierarchy expert package
# (docs/guides/synthetic-release.md).
set -euo pipefail
cd "$(dirname "$0")/../.."
export OMP_NUM_THREADS=1
out=runs/release-v3/experts
mkdir -p runs/release-v3

train() {  # snippet [extra flags]
    local snippet=$1
    shift
    mocap-hierarchy expert train --snippet "$snippet" --out $out --profile fast-3m-wide \
        --eval-episodes "50@0,500@2M" "$@"
}

lane_walking() {
    for snippet in SYN_walk_slow-0-182 SYN_walk_fast-0-182 SYN_walk_backward-0-182; do train $snippet; done
}

lane_turning() {
    for snippet in SYN_turn_left-0-182 SYN_turn_right-0-182; do train $snippet; done
    train SYN_stand-0-181 --steps 400000
    train SYN_wave-0-196 --steps 675000
}

lane_walking > runs/release-v3/lane_walking.log 2>&1 &
walking=$!
lane_turning > runs/release-v3/lane_turning.log 2>&1 &
turning=$!
wait $walking $turning
