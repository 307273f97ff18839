#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-straight-ahead-1500k.md: velocity control with commands straight ahead
# around the synthetic-v2 prior, three seeds to 600k, 1M and 1.5M (policies copied aside at each budget).
# Expected time on a 2-core CPU machine: about an hour (41 minutes to 1M, 16 minutes from 1M to 1.5M, three side
# by side). The recording needs MUJOCO_GL=osmesa (apt-get install libosmesa6).
set -euo pipefail
cd "$(dirname "$0")/.."

folder=runs/forward_1m/velocity_control/decoder_v2_prior
train() {  # budget
    local pids=()
    for seed in 0 1 2; do
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v2 \
            --latent-prior synthetic-v2 --out $folder/seed$seed --seed $seed \
            --initial-std 1.0 --set max_speed=1.5 heading_spread=0 --steps "$1" --n-envs 8 --steps-per-update 4096 \
            --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs \
            --checkpoint-every 100000 &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
}
set_aside() {  # label
    for seed in 0 1 2; do
        mkdir -p "runs/forward_$1/seed$seed"
        cp $folder/seed$seed/policy.safetensors $folder/seed$seed/transfer.json "runs/forward_$1/seed$seed/"
    done
}

train 600000
set_aside 600k_policies
python experiments/transfer_table.py runs/forward_1m --until 600000
python experiments/speed_tracking.py runs/forward_600k_policies/seed{0,1,2}/policy.safetensors --episodes 30 \
    --out runs/forward_600k_policies/speed_tracking.png
train 1000000
set_aside 1m_policies
python experiments/transfer_table.py runs/forward_1m
python experiments/speed_tracking.py $folder/seed0 $folder/seed1 $folder/seed2 --episodes 30 \
    --out docs/figures/speed_tracking_forward_1m.png
MUJOCO_GL=osmesa mocap-hierarchy record --task velocity_control \
    --policy runs/forward_1m/velocity_control/decoder_v2_prior/seed0/policy.safetensors --set max_steps=600 \
    --out vc_1m.rrd --video docs/figures/velocity_control_1m.mp4 --filmstrip docs/figures/velocity_control_1m.png
train 1500000
python experiments/transfer_table.py runs/forward_1m
python experiments/speed_tracking.py $folder/seed0 $folder/seed1 $folder/seed2 --episodes 30 \
    --out docs/figures/speed_tracking_forward_1500k.png
