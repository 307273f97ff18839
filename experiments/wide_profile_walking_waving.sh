#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-wide-profile-walking-waving.md:
# --profile fast-3m-wide, unchanged, on SYN_walk_slow-0-182, SYN_wave-0-196 and SYN_walk_fast-0-182 (seed 0,
# 3M steps), the replots with the table's span means, the wave expert over 1000 episodes,
# and the profile's cost per step against fast-3m.
# Expected time: about 97-118 minutes per walking run to 3M on a core of its own of a 2-core CPU machine
# (walk slow and wave side by side first; wave passes 0.99 by 550k and was stopped at 675k as measured).
set -euo pipefail
cd "$(dirname "$0")/.."

# --eval-episodes 50 sets one evaluation size for the whole run, so the variants give the profile's
# 500 episodes from 2M again (eval_episodes=50@0;500@2M: what the measured runs evaluated with).
# The measured runs also kept a snapshot of their 2M state (snapshot_steps, removed on 2026-11-26); it changed
# nothing in training and nothing here starts from it, so it is left out.
python experiments/expert_learning.py --out runs/wide_profile --snippets SYN_walk_slow-0-182 SYN_wave-0-196 \
    --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast-3m-wide --seeds 0 \
    --variant "fast-3m-wide:eval_episodes=50@0;500@2M"
python experiments/expert_learning.py --out runs/wide_walk_fast --snippets SYN_walk_fast-0-182 \
    --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m-wide --seeds 0 \
    --variant "fast-3m-wide:eval_episodes=50@0;500@2M"
python experiments/expert_learning.py --out runs/wide_profile --replot --snippets SYN_walk_slow-0-182 \
    --steps 3000000 --seeds 0 --variant "fast-3m-wide:eval_episodes=50@0;500@2M" \
    --span 550000 1000000 --span 1050000 1500000 --span 1550000 2000000 --span 2050000 2500000 --span 2550000 3020000
python experiments/expert_learning.py --out runs/wide_walk_fast --replot --snippets SYN_walk_fast-0-182 \
    --steps 3000000 --seeds 0 --variant "fast-3m-wide:eval_episodes=50@0;500@2M" \
    --span 550000 1000000 --span 1050000 1500000 --span 1550000 2000000 --span 2050000 2500000 --span 2550000 3020000
mocap-hierarchy expert eval runs/wide_profile/fast-3m-wide/seed0/SYN_wave-0-196 --seed 1   # the wave run's kept expert
python benchmarks/expert_throughput.py --profiles fast-3m fast-3m-wide --trials 3
