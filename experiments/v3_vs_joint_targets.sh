#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-v3-vs-joint-targets.md: velocity control with commands straight ahead on
# joint targets, three seeds x 300k, seeds 0-1 on to 1M, against the synthetic-v3 runs.
# Expected time on a 2-core CPU machine: about an hour (37 minutes to 300k, 20 minutes from 300k to 1M).
# Needs runs/forward_v3 (1M) and runs/forward_v3_300k from experiments/v3_straight_ahead_300k.sh and
# experiments/v3_straight_ahead_1m.sh.
set -euo pipefail
cd "$(dirname "$0")/.."

joints() {  # steps seeds...
    local steps=$1 pids=()
    shift
    for seed in "$@"; do
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control \
            --out runs/forward_joints/velocity_control/joints/seed$seed --seed $seed --set max_speed=1.5 heading_spread=0 \
            --steps $steps --n-envs 8 --steps-per-update 4096 --minibatch-size 512 --hidden-layers 256 256 \
            --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
}

joints 300000 0 1 2
rm -rf runs/forward_joints_300k && cp -r runs/forward_joints runs/forward_joints_300k
python experiments/transfer_table.py runs/forward_v3/velocity_control/decoder_v3_prior runs/forward_joints_300k \
    --until 303104
joints 1000000 0 1
python experiments/transfer_table.py runs/forward_v3/velocity_control/decoder_v3_prior \
    runs/forward_joints/velocity_control/joints/seed0 runs/forward_joints/velocity_control/joints/seed1

# The 1M runs side by side (joint targets: seeds 0-1).
rm -rf runs/forward_cmp && mkdir -p runs/forward_cmp/velocity_control/decoder_v3_prior runs/forward_cmp/velocity_control/joints
for seed in 0 1 2; do
    mkdir -p runs/forward_cmp/velocity_control/decoder_v3_prior/seed$seed
    cp runs/forward_v3/velocity_control/decoder_v3_prior/seed$seed/{progress.csv,transfer.json} \
        runs/forward_cmp/velocity_control/decoder_v3_prior/seed$seed/
done
for seed in 0 1; do
    mkdir -p runs/forward_cmp/velocity_control/joints/seed$seed
    cp runs/forward_joints/velocity_control/joints/seed$seed/{progress.csv,transfer.json} \
        runs/forward_cmp/velocity_control/joints/seed$seed/
done
mocap-hierarchy report runs/forward_cmp
cp runs/forward_cmp/report/transfer_curves.png docs/figures/transfer_curves_forward_v3_1m.png
