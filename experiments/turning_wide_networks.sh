#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-turning-wide-networks.md:
# 2x512 networks at half the step sizes (what is now --profile fast-3m-wide) on SYN_turn_left-0-182, seeds 0
# and 1, against the 2x256 runs of runs/turn_batch/batch16k-from-2M
# (from experiments/turning_larger_updates_within_3m.sh).
# Expected time: about 115 minutes per run, two side by side, on a 2-core CPU machine; then two
# 1000-episode evaluations.
set -euo pipefail
cd "$(dirname "$0")/.."

# wide2x512 is --profile fast-3m-wide; eval_episodes=50@0;500@2M because --eval-episodes 50 sets one size for
# the whole run. The measured runs also kept a snapshot of their 2M state (snapshot_steps, removed on 2026-11-26);
# it changed nothing in training and nothing here starts from it, so it is left out.
python experiments/expert_learning.py --out runs/turn_wide --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast-3m --seeds 0 1 \
    --variant "wide2x512:hidden_layers=512;512,learning_rate=1.5e-4@0;5e-5@600k,steps_per_update=4096@0;16384@2M,eval_episodes=50@0;500@2M"
ln -sf ../turn_batch/batch16k-from-2M runs/turn_wide/    # the baseline runs of "within 3M"
python experiments/expert_learning.py --out runs/turn_wide --replot --per-seed --snippets SYN_turn_left-0-182 \
    --steps 3000000 --seeds 0 1 --variant "batch16k-from-2M:steps_per_update=4096@0;16384@2M" \
    --variant "wide2x512:hidden_layers=512;512,learning_rate=1.5e-4@0;5e-5@600k,steps_per_update=4096@0;16384@2M,eval_episodes=50@0;500@2M" \
    --span 550000 1000000 --span 1050000 1500000 --span 1550000 2000000 --span 2050000 2500000 --span 2550000 3020000
mocap-hierarchy expert eval runs/turn_wide/wide2x512/seed0/SYN_turn_left-0-182 --episodes 1000 --seed 1
mocap-hierarchy expert eval runs/turn_wide/wide2x512/seed1/SYN_turn_left-0-182 --episodes 1000 --seed 1
