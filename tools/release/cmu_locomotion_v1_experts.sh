#!/usr/bin/env bash
# Trains the first real expert group, cmu-locomotion-v1: 24 snippets of the shipped real clip library covering
# every kind it holds, with the synthetic release's recipe (--profile fast-3m-wide, one seed) on a budget of
# 1M steps each (BUDGET). The first four experts (a walk, a run, two turns) trained for 1.5M steps and reached
# success 1.0 on their evaluations by 0.4-0.9M, with G-MPJPE still falling slowly after: 1M buys the remaining
# twenty a third less time. Forward jumps learn slower (CMU_013_11 reached 0.94 of its snippet only at 1M,
# CMU_105_39 was at 0.78 at 550k), so the other two train for 2M (JUMP_BUDGET), still within the profile's
# first stretch (its schedules change at 2M). The budget may change on resume: rerun with a larger BUDGET while a
# run is short of 0.9 and it continues exactly where it stopped (a finished run keeps no checkpoint). Two lanes
# side by side on a 2-core machine, at low priority so interactive work comes first; each lane trains one expert
# of every kind first, then the rest, and the lanes' budgets are about equal.
# Resumable: rerun it after a kill (or in a new session) and every expert continues from its checkpoint; finished
# ones are skipped. Where every run stands: python -m tools.release.expert_status runs/release-cmu-v1/experts
set -euo pipefail
cd "$(dirname "$0")/../.."
export OMP_NUM_THREADS=1
[ -z "${VIRTUAL_ENV:-}" ] && [ -f .venv/bin/activate ] && . .venv/bin/activate  # the README install
out=runs/release-cmu-v1/experts
first=runs/release-cmu-v1/experts-first  # the first runs of the continued ones
mkdir -p $out

train() {  # snippet [extra flags]
    local snippet=$1
    shift
    if [ -f "$out/$snippet/done.json" ]; then return 0; fi  # finished: skipped
    # continued (its first run moved away): its `continued` line below resumes it, with the same settings
    if [ -d "$first/$snippet" ] && [ $# -eq 0 ]; then return 0; fi
    nice -n 10 mocap-hierarchy expert train --snippet "$snippet" --clips cmu-locomotion-v1 --out $out \
        --profile fast-3m-wide --eval-episodes "50@0,500@2M" --steps "${BUDGET:-1000000}" "$@"
}

continued() {  # snippet steps: a finished run continues from its kept expert (its first run moves to experts-first/)
    local snippet=$1 steps=$2
    if [ ! -d "$first/$snippet" ]; then
        mkdir -p "$first"
        mv "$out/$snippet" "$first/"
    fi
    train "$snippet" --steps "$steps" --start-from "$first"
}

lane_a() {  # walks, veers and turns, walking and running
    for snippet in CMU_016_22-0-82 CMU_016_27-0-64 CMU_016_23-0-79 CMU_016_51-0-46 CMU_016_48-0-32 \
        CMU_002_01-0-92 CMU_016_28-0-72 CMU_016_30-0-70 CMU_105_36-0-138 CMU_016_36-0-49 CMU_105_62-0-192 \
        CMU_016_25-0-75; do
        train $snippet
    done
    # The walk of 4.6 s kept 0.899 of its snippet at 1M over the 1000 episodes (0.94 in training's last
    # evaluations of 50): it continues from its kept expert to 1.5M.
    continued CMU_105_36-0-138 1500000
    # The curved walk of 6.4 s stalled at 0.66-0.74 of its snippet from 400k to 900k: it continues to the profile's
    # full 3M, through its second stretch (less noise, larger updates from 2M).
    continued CMU_105_62-0-192 3000000
}

lane_b() {  # runs, jumps, jump-turns, turns on the spot
    for snippet in CMU_016_55-0-47 CMU_016_29-0-75 CMU_013_11-0-112 CMU_105_46-0-86 CMU_105_56-0-135 \
        CMU_016_53-0-36 CMU_016_49-0-32 CMU_009_11-0-42 CMU_105_39-0-120 CMU_105_48-0-118 CMU_016_02-0-126 \
        CMU_105_53-0-150; do
        case $snippet in
            CMU_105_39-0-120 | CMU_016_02-0-126) train $snippet --steps "${JUMP_BUDGET:-2000000}" ;;  # forward jumps
            *) train $snippet ;;
        esac
    done
    # The second turn on the spot (5 s) kept 0.886 of its snippet at 1M over the 1000 episodes (success 0.31): it
    # continues from its kept expert to 1.5M, as the longest walk did.
    continued CMU_105_53-0-150 1500000
}

lane_a > $out/../lane_a.log 2>&1 &
a=$!
lane_b > $out/../lane_b.log 2>&1 &
b=$!
wait $a $b
# Every expert has finished: the rest of the release follows at once (NEXT=0 stops here); its log is
# runs/release-cmu-v1/decoder.log.
if [ "${NEXT:-1}" = 1 ]; then
    exec tools/release/cmu_v1_decoder.sh > $out/../decoder.log 2>&1
fi
