#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-commands-within-skills.md: velocity control on synthetic-v1 with the
# paper's commands (to 4.5 m/s) against commands to 1.5 m/s, and one change each (initial std 1.0; 5 control
# steps per latent), one seed, 1M steps.
# Expected time on a 2-core CPU machine: about 1.5 hours (two runs side by side, 45 minutes each pair).
set -euo pipefail
cd "$(dirname "$0")/.."

common=(--n-envs 8 --steps-per-update 4096 --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4
    --no-subprocess-envs --checkpoint-every 100000 --seed 0)

OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v1 --out runs/vc/max1.5 \
    --set max_speed=1.5 --steps 1000000 "${common[@]}" &
first=$!
OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v1 --out runs/vc/seed_task \
    --steps 1000000 "${common[@]}" &
second=$!
wait "$first"; wait "$second"

OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v1 --out runs/vc/std1 \
    --set max_speed=1.5 --initial-std 1.0 --steps 1000000 "${common[@]}" &
first=$!
OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v1 --out runs/vc/k5 \
    --set max_speed=1.5 --steps-per-latent 5 --steps 200000 "${common[@]}" &
second=$!
wait "$first"; wait "$second"

mocap-hierarchy report runs/vc
cp runs/vc/report/transfer_curves.png docs/figures/velocity_control_curves.png
python experiments/speed_tracking.py runs/vc/max1.5 runs/vc/std1 runs/vc/k5 runs/vc/seed_task --episodes 50 \
    --labels "to 1.5 m/s" "to 1.5 m/s, std 1.0" "to 1.5 m/s, 5 steps per latent" "to 4.5 m/s (paper)" \
    --zero-latent synthetic-v1 --out docs/figures/speed_tracking.png
python experiments/decoder_balance.py
