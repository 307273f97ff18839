#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-turning-noise-schedules.md:
# --profile fast-3m on SYN_turn_left-0-182 with the noise drop at 1.4M, and with a third phase (0.15 from
# 2.5M), side by side from scratch; then a second seed of the recipe; replots with the table's span means.
# Expected time: 75.6 minutes for the two variants side by side, 2.4 h for the second seed (measured on a
# 2-core CPU machine beside other jobs).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/expert_learning.py --out runs/turn_noise --snippets SYN_turn_left-0-182 \
    --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast-3m \
    --variant "std0.2-at-1.4M:action_std=0.3@0;0.2@1.4M" \
    --variant "std0.15-at-2.5M:action_std=0.3@0;0.2@2M;0.15@2.5M"
python experiments/expert_learning.py --out runs/turn_noise --replot --snippets SYN_turn_left-0-182 \
    --steps 3000000 --span 1425000 2025000 --span 2025000 2525000 --span 2525000 3100000   # the table's means
python experiments/expert_learning.py --out runs/turn_seeds --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m --variant recipe --seeds 1
python experiments/expert_learning.py --out runs/turn_seeds --replot --snippets SYN_turn_left-0-182 --steps 3000000 \
    --span 1450000 2000000 --span 2050000 2500000 --span 2550000 3002368
