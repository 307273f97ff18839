#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-straight-ahead-600k.md: seeds 0 and 2 of the synthetic-v2 prior runs with
# commands straight ahead, resumed from 300k to 600k.
# Expected time on a 2-core CPU machine: 15 minutes (two side by side).
# Needs runs/forward from experiments/straight_ahead_300k.sh.
set -euo pipefail
cd "$(dirname "$0")/.."

mkdir -p runs/forward_long/velocity_control/decoder_v2_prior
pids=()
for seed in 0 2; do
    cp -r runs/forward/velocity_control/decoder_v2_prior/seed$seed runs/forward_long/velocity_control/decoder_v2_prior/
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v2 \
        --latent-prior synthetic-v2 --out runs/forward_long/velocity_control/decoder_v2_prior/seed$seed --seed $seed \
        --initial-std 1.0 --set max_speed=1.5 heading_spread=0 --steps 600000 --n-envs 8 --steps-per-update 4096 \
        --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs \
        --checkpoint-every 100000 &
    pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done

python experiments/speed_tracking.py runs/forward_long/velocity_control/decoder_v2_prior/seed0 \
    runs/forward_long/velocity_control/decoder_v2_prior/seed2 --episodes 30 --out docs/figures/speed_tracking_forward_600k.png
