#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-21-quickstart-velocity-with-without-decoder.md: velocity control on the
# quickstart's own decoder against joint targets, 8192 steps each (the quickstart's velocity stage of 2026-11-21).
# Expected time on a 2-core CPU machine: the quickstart (about 13 minutes) plus a few minutes.
set -euo pipefail
cd "$(dirname "$0")/.."

mocap-hierarchy quickstart --out runs/quickstart   # for runs/quickstart/distill/decoder.safetensors
mocap-hierarchy transfer train --task velocity_control --decoder runs/quickstart/distill/decoder.safetensors \
    --out runs/quickstart_2026-11-21/velocity_decoder --set max_steps=500 --steps 8192 --n-envs 4 \
    --steps-per-update 2048 --hidden-layers 256 256 --learning-rate 3e-4
mocap-hierarchy transfer train --task velocity_control --out runs/quickstart_2026-11-21/velocity_joints \
    --set max_steps=500 --steps 8192 --n-envs 4 --steps-per-update 2048 --hidden-layers 256 256 --learning-rate 3e-4
mocap-hierarchy transfer eval runs/quickstart_2026-11-21/velocity_decoder --episodes 5
mocap-hierarchy transfer eval runs/quickstart_2026-11-21/velocity_joints --episodes 5
mocap-hierarchy report runs/quickstart_2026-11-21
