#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-go-to-target-300k.md: go-to-target on synthetic-v1 and on joint targets,
# then on synthetic-v2, three seeds x 300k.
# Expected time on a 2-core CPU machine: 51 minutes for the six synthetic-v1 and joint-target runs (one at a time,
# beside one expert run), then the three synthetic-v2 runs (three at a time; not timed).
set -euo pipefail
cd "$(dirname "$0")/.."

OMP_NUM_THREADS=1 python experiments/transfer_learning.py --decoder synthetic-v1 --out runs/gtt --tasks go_to_target \
    --seeds 0 1 2 --steps 300000 --set n_envs=8 steps_per_update=4096 minibatch_size=512 \
    hidden_layers=256,256 learning_rate=3e-4 checkpoint_every=100000 --jobs 1
mocap-hierarchy report runs/gtt
cp runs/gtt/report/transfer_curves.png docs/figures/transfer_curves_gtt.png

# synthetic-v2: the joint-target runs copied in from runs/gtt (finished runs are not trained again).
mkdir -p runs/gtt_v2/go_to_target
cp -r runs/gtt/go_to_target/joints runs/gtt_v2/go_to_target/
OMP_NUM_THREADS=1 python experiments/transfer_learning.py --decoder synthetic-v2 --out runs/gtt_v2 --tasks go_to_target \
    --seeds 0 1 2 --steps 300000 --set n_envs=8 steps_per_update=4096 minibatch_size=512 \
    hidden_layers=256,256 learning_rate=3e-4 checkpoint_every=100000 --jobs 3
python experiments/transfer_table.py runs/gtt runs/gtt_v2
