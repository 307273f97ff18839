#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-decoder-vs-joints-100k.md: PPO on synthetic-v1 against PPO on joint
# targets, 100k steps, velocity control and go-to-target, three seeds each.
# Expected time on a 2-core CPU machine: not recorded when measured (12 runs of 100k steps).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/transfer_learning.py --decoder synthetic-v1 --out runs/transfer --tasks velocity_control go_to_target \
    --seeds 0 1 2 --steps 100000 --set n_envs=8 steps_per_update=4096 minibatch_size=512 hidden_layers=256,256 \
    learning_rate=3e-4
mocap-hierarchy report runs/transfer
cp runs/transfer/report/transfer_curves.png docs/figures/transfer_curves.png
mocap-hierarchy record --task velocity_control --policy runs/transfer/velocity_control/decoder/seed1/policy.safetensors \
    --out runs/transfer/velocity_control_decoder_seed1.rrd
