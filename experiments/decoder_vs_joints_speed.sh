#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-decoder-vs-joints-speed.md: velocity control with commands to 1.5 m/s,
# synthetic-v1 (initial std 2.5 and 1.0) and synthetic-v2 (std 1.0) against joint targets, three seeds x 300k.
# Expected time on a 2-core CPU machine: about 1.5-2 hours (three runs side by side take about 25 minutes).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/transfer_learning.py --decoder synthetic-v1 --out runs/transfer_speed --tasks velocity_control \
    --seeds 0 1 2 --steps 300000 --task-set max_speed=1.5 --set n_envs=8 steps_per_update=4096 \
    minibatch_size=512 hidden_layers=256,256 learning_rate=3e-4 checkpoint_every=100000 --jobs 2

# Initial std 1.0 on synthetic-v1 (seed 0 was measured as the first 300k of runs/vc/std1) and on synthetic-v2.
pids=()
for seed in 0 1 2; do
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v1 \
        --out runs/transfer_speed/velocity_control/decoder_std1/seed$seed --seed $seed --initial-std 1.0 --set max_speed=1.5 \
        --steps 300000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 --hidden-layers 256 256 \
        --learning-rate 3e-4 --no-subprocess-envs &
    pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done
pids=()
for seed in 0 1 2; do
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v2 \
        --out runs/transfer_speed/velocity_control/decoder_v2_std1/seed$seed --seed $seed --initial-std 1.0 --set max_speed=1.5 \
        --steps 300000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 --hidden-layers 256 256 \
        --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
    pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done

mocap-hierarchy report runs/transfer_speed
cp runs/transfer_speed/report/transfer_curves.png docs/figures/transfer_curves_speed.png
python experiments/speed_tracking.py runs/transfer_speed/velocity_control/decoder/seed0 \
    runs/transfer_speed/velocity_control/joints/seed0 --episodes 50 --out runs/transfer_speed/speed_tracking_v1_joints.png
python experiments/speed_tracking.py runs/transfer_speed/velocity_control/decoder_std1/seed1 \
    runs/transfer_speed/velocity_control/decoder_v2_std1/seed1 runs/transfer_speed/velocity_control/decoder_v2_std1/seed0 \
    --episodes 50 --zero-latent synthetic-v2 --out runs/transfer_speed/speed_tracking_v1_v2.png
