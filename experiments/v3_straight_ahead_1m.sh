#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-v3-straight-ahead-1m.md: the three synthetic-v3 runs with commands straight
# ahead, resumed from 300k to 1M; speed tracking and a recording of seed 0.
# Expected time on a 2-core CPU machine: about 80 minutes (measured beside up to nine other runs).
# Needs runs/forward_v3 from experiments/v3_straight_ahead_300k.sh. The recording needs MUJOCO_GL=osmesa
# (apt-get install libosmesa6).
set -euo pipefail
cd "$(dirname "$0")/.."

folder=runs/forward_v3/velocity_control/decoder_v3_prior
pids=()
for seed in 0 1 2; do
    mkdir -p runs/forward_v3_300k/seed$seed
    cp $folder/seed$seed/policy.safetensors $folder/seed$seed/transfer.json runs/forward_v3_300k/seed$seed/
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v3 \
        --latent-prior synthetic-v3 --out $folder/seed$seed --seed $seed \
        --initial-std 1.0 --set max_speed=1.5 heading_spread=0 --steps 1000000 --n-envs 8 --steps-per-update 4096 \
        --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs \
        --checkpoint-every 100000 &
    pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done

python experiments/transfer_table.py $folder --until 600000
python experiments/transfer_table.py $folder
python experiments/speed_tracking.py $folder/seed{0,1,2} --episodes 30 \
    --labels "v3 seed 0, 1M" "v3 seed 1, 1M" "v3 seed 2, 1M" --out docs/figures/speed_tracking_forward_v3_1m.png
MUJOCO_GL=osmesa mocap-hierarchy record --task velocity_control \
    --policy runs/forward_v3/velocity_control/decoder_v3_prior/seed0/policy.safetensors --set max_steps=600 \
    --out runs/vc_v3_1m.rrd --video docs/figures/velocity_control_v3_1m.mp4 --filmstrip docs/figures/velocity_control_v3_1m.png
