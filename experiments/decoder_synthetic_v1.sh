#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-decoder-synthetic-v1.md: the shipped decoder synthetic-v1,
# from its seven --profile fast experts to the packaged decoder (the commands of its model card,
# hierarchy/pretrained/cards/synthetic-v1.card.json).
# Expected time on a 2-core CPU machine: about 2.5 hours (experts about an hour per batch,
# rollout 2 minutes, distillation 26 minutes, evaluation about a minute).
set -euo pipefail
cd "$(dirname "$0")/.."

# Experts: the measured runs were stopped by hand at 550-650k and 850-925k steps.
python experiments/expert_learning.py --out runs/long --snippets SYN_walk_slow-0-182 SYN_wave-0-196 SYN_turn_left-0-182 \
    --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 4 --profile fast --variant fast
python experiments/expert_learning.py --out runs/long --snippets SYN_stand-0-181 SYN_walk_fast-0-182 SYN_turn_right-0-182 \
    SYN_walk_backward-0-182 --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 4 --profile fast --variant fast

mocap-hierarchy rollout --experts runs/long/fast/seed0 --out runs/synthetic-v1/dataset --n-start 20 --n-rsi 80 --workers 2
mocap-hierarchy distill train --data runs/synthetic-v1/dataset --out runs/synthetic-v1/distill --steps 2258 \
    --batch-size 128 --encoder-layers 512 512 --decoder-layers 512 512 512
mocap-hierarchy distill eval runs/synthetic-v1/distill --data runs/synthetic-v1/dataset --episodes 50 \
    --json runs/synthetic-v1/distill_eval.json
# The card's command writes hierarchy/pretrained/synthetic-v1.safetensors; here the copy goes to runs/.
mocap-hierarchy decoder package runs/synthetic-v1/distill/decoder.safetensors runs/synthetic-v1/synthetic-v1.safetensors \
    --card hierarchy/pretrained/cards/synthetic-v1.card.json --scores runs/synthetic-v1/distill_eval.json
mocap-hierarchy decoder card runs/synthetic-v1/synthetic-v1.safetensors --out runs/synthetic-v1/synthetic-v1.md
