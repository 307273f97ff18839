#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-turning-larger-updates-4m.md:
# two branches of the seed-1 --profile fast-3m turning expert kept at 2.9M (runs/turn_seeds/recipe/seed1,
# from experiments/turning_noise_schedules.sh) to 4M: unchanged, and 16,384 steps per update.
# Expected time: 72 minutes of training per branch, side by side, then the 1000-episode evaluations
# (measured on a 2-core CPU machine beside other jobs).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/expert_learning.py --out runs/turn_kept --snippets SYN_turn_left-0-182 --steps 4000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast-3m --seeds 1 \
    --variant continued:start_from=runs/turn_seeds/recipe/seed1 \
    --variant batch16k:steps_per_update=16384,start_from=runs/turn_seeds/recipe/seed1
python experiments/expert_learning.py --out runs/turn_kept --replot --snippets SYN_turn_left-0-182 \
    --steps 4000000 --span 2950000 3450000 --span 3500000 4000000
