#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-decoder-synthetic-v2.md: the shipped decoder synthetic-v2 and its
# latent prior, from its seven experts (the commands of hierarchy/pretrained/cards/synthetic-v2.card.json).
# Expected time on a 2-core CPU machine: about 6 hours of expert training (2.3-2.4 hours for the longest runs
# with two to four jobs sharing the cores), rollout 75 s, distillation 17 minutes, evaluation 50 s, prior 74 s.
set -euo pipefail
cd "$(dirname "$0")/.."

# The card records the expert commands in the settings names of the time; here they are in today's
# (one schedule value per setting and start_from for branch_from since 2026-11-26), with the same settings.

# Walk slow: the measured run was stopped just past 2M and copied to runs/snapshots/walk2M; here it stops at 2M.
python experiments/expert_learning.py --out runs/late --snippets SYN_walk_slow-0-182 --steps 2000000 --eval-every 50000 \
    --eval-episodes 50 --jobs 1 --profile fast --variant "two-phase:learning_rate=3e-4@0;1e-4@600k"
mkdir -p runs/snapshots && cp -r runs/late/two-phase runs/snapshots/walk2M
python experiments/expert_learning.py --out runs/late_branch --snippets SYN_walk_slow-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant std0.2:learning_rate=1e-4,action_std=0.2,start_from=runs/snapshots/walk2M/seed0
python experiments/expert_learning.py --out runs/recipe --snippets SYN_turn_left-0-182 SYN_walk_fast-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant "recipe:learning_rate=3e-4@0;1e-4@600k,action_std=0.3@0;0.2@2M"
python experiments/expert_learning.py --out runs/v2a --snippets SYN_turn_right-0-182 SYN_walk_backward-0-182 --steps 2000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant "recipe:learning_rate=3e-4@0;1e-4@600k,action_std=0.3@0;0.2@1.4M"
# Stand: the measured run was stopped at 405k (best 0.993 at 352k).
python experiments/expert_learning.py --out runs/v2b --snippets SYN_stand-0-181 SYN_wave-0-196 --steps 800000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant "recipe:learning_rate=3e-4@0;1e-4@600k"

mocap-hierarchy rollout --experts runs/v2b/recipe/seed0 runs/v2a/recipe/seed0 runs/recipe/recipe/seed0 \
    runs/late_branch/std0.2/seed0 --out runs/synthetic-v2/dataset --n-start 20 --n-rsi 80 --workers 2
mocap-hierarchy distill train --data runs/synthetic-v2/dataset --out runs/synthetic-v2/distill --steps 2258 \
    --batch-size 128 --encoder-layers 512 512 --decoder-layers 512 512 512
mocap-hierarchy distill eval runs/synthetic-v2/distill --data runs/synthetic-v2/dataset --episodes 50 \
    --json runs/synthetic-v2/distill_eval.json
# The card's command writes hierarchy/pretrained/synthetic-v2.safetensors; here the copy goes to runs/.
mocap-hierarchy decoder package runs/synthetic-v2/distill/decoder.safetensors runs/synthetic-v2/synthetic-v2.safetensors \
    --card hierarchy/pretrained/cards/synthetic-v2.card.json --scores runs/synthetic-v2/distill_eval.json
mocap-hierarchy decoder card runs/synthetic-v2/synthetic-v2.safetensors --out runs/synthetic-v2/synthetic-v2.md
# The latent prior (40 episodes per snippet, 25,493 states, 4000 Adam steps: 74 s on 2 cores).
OMP_NUM_THREADS=1 mocap-hierarchy decoder fit-prior runs/synthetic-v2/distill/policy.safetensors \
    runs/synthetic-v2/synthetic-v2.safetensors runs/prior/synthetic-v2.safetensors --data runs/synthetic-v2/dataset
python experiments/decoder_balance.py --decoder runs/synthetic-v2/synthetic-v2.safetensors
