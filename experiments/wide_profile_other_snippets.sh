#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-wide-profile-other-snippets.md:
# --profile fast-3m-wide, unchanged, on SYN_turn_right-0-182 and SYN_walk_backward-0-182 (3M steps) and
# SYN_stand-0-181 (400k), seed 0, with the replots' span means.
# Expected time: roughly 2 hours per 3M run with two runs sharing a 2-core CPU machine (the synthetic-v3
# card records 115-133 minutes per 3M run); standing is much shorter (0.9 after 7 minutes).
set -euo pipefail
cd "$(dirname "$0")/.."

# --eval-episodes 50 sets one evaluation size for the whole run, so the variants give the profile's
# 500 episodes from 2M again (eval_episodes=50@0;500@2M: what the measured runs evaluated with).
# The measured runs also kept a snapshot of their 2M state (snapshot_steps, removed on 2026-11-26); it changed
# nothing in training and nothing here starts from it, so it is left out.
python experiments/expert_learning.py --out runs/wide_v3 --snippets SYN_turn_right-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m-wide --seeds 0 \
    --variant "fast-3m-wide:eval_episodes=50@0;500@2M"
python experiments/expert_learning.py --out runs/wide_v3b --snippets SYN_walk_backward-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m-wide --seeds 0 \
    --variant "fast-3m-wide:eval_episodes=50@0;500@2M"
python experiments/expert_learning.py --out runs/wide_stand --snippets SYN_stand-0-181 --steps 400000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m-wide --seeds 0
python experiments/expert_learning.py --out runs/wide_v3 --replot --snippets SYN_turn_right-0-182 \
    --steps 3000000 --seeds 0 --variant "fast-3m-wide:eval_episodes=50@0;500@2M" \
    --span 550000 1000000 --span 1050000 1500000 --span 1550000 2000000 --span 2050000 2500000 --span 2550000 3020000
python experiments/expert_learning.py --out runs/wide_v3b --replot --snippets SYN_walk_backward-0-182 \
    --steps 3000000 --seeds 0 --variant "fast-3m-wide:eval_episodes=50@0;500@2M" \
    --span 550000 1000000 --span 1050000 1500000 --span 1550000 2000000 --span 2050000 2500000 --span 2550000 3020000
