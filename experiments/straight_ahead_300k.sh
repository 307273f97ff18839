#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-straight-ahead-300k.md: velocity control with commands straight ahead
# below 1.5 m/s on synthetic-v2, around its latent prior against plain latents, three seeds x 300k.
# Expected time on a 2-core CPU machine: under an hour (three runs side by side, about 25 minutes per three).
set -euo pipefail
cd "$(dirname "$0")/.."

for setting in prior plain; do
    pids=()
    for seed in 0 1 2; do
        prior_flags=()
        if [ "$setting" = prior ]; then prior_flags=(--latent-prior synthetic-v2); fi
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v2 \
            "${prior_flags[@]}" --out runs/forward/velocity_control/decoder_v2_$setting/seed$seed --seed $seed \
            --initial-std 1.0 --set max_speed=1.5 heading_spread=0 --steps 300000 --n-envs 8 --steps-per-update 4096 \
            --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs \
            --checkpoint-every 100000 &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
done

mocap-hierarchy report runs/forward
cp runs/forward/report/transfer_curves.png docs/figures/transfer_curves_forward.png
python experiments/speed_tracking.py runs/forward/velocity_control/decoder_v2_prior/seed0 \
    runs/forward/velocity_control/decoder_v2_prior/seed1 runs/forward/velocity_control/decoder_v2_prior/seed2 \
    runs/forward/velocity_control/decoder_v2_plain/seed1 --episodes 30 --out docs/figures/speed_tracking_forward.png
