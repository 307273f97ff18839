#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-v3-any-direction.md: velocity control with commands in any direction around
# the synthetic-v3 prior, three seeds x 300k, seeds 0-1 on to 1M.
# Expected time on a 2-core CPU machine: about 70 minutes (47 minutes to 300k when measured beside nine other runs,
# 18 minutes from 300k to 1M for two side by side).
set -euo pipefail
cd "$(dirname "$0")/.."

folder=runs/any_v3/velocity_control/decoder_v3_prior
train() {  # steps seeds...
    local steps=$1 pids=()
    shift
    for seed in "$@"; do
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v3 \
            --latent-prior synthetic-v3 --out $folder/seed$seed --seed $seed \
            --initial-std 1.0 --set max_speed=1.5 --steps $steps --n-envs 8 --steps-per-update 4096 \
            --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs \
            --checkpoint-every 100000 &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
}

train 300000 0 1 2
python experiments/transfer_table.py runs/any_v3
mocap-hierarchy report runs/any_v3
cp runs/any_v3/report/transfer_curves.png docs/figures/transfer_curves_any_v3.png
python experiments/speed_tracking.py $folder/seed{0,1,2} --episodes 30 \
    --labels "v3 seed 0" "v3 seed 1" "v3 seed 2" --out docs/figures/speed_tracking_any_v3.png

rm -rf runs/any_v3_300k && cp -r runs/any_v3 runs/any_v3_300k
train 1000000 0 1
python experiments/transfer_table.py $folder/seed0 $folder/seed1
python experiments/speed_tracking.py $folder/seed0 $folder/seed1 --episodes 30 --out docs/figures/speed_tracking_any_v3_1m.png
