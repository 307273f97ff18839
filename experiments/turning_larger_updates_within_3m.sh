#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-turning-larger-updates-within-3m.md:
# --profile fast-3m on SYN_turn_left-0-182 with 16,384 steps per update from 2M (seeds 0 and 1), the recipe
# without the schedule (seed 0), and the switch at 1.4M (seeds 0 and 1); per-seed replots; every kept expert
# over 1000 other episodes (evaluation seed 1).
# Expected time: 76 minutes per 2M-switch run and 81 per 1.4M-switch run, two side by side, plus the baseline
# (not timed), on a 2-core CPU machine.
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/expert_learning.py --out runs/turn_batch --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast-3m --seeds 0 1 \
    --variant "batch16k-from-2M:steps_per_update=4096@0;16384@2M"
python experiments/expert_learning.py --out runs/turn_batch_base --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m --seeds 0 --variant recipe
ln -sfn ../turn_batch_base/recipe runs/turn_batch/recipe   # one figure for both
python experiments/expert_learning.py --out runs/turn_batch --replot --per-seed --snippets SYN_turn_left-0-182 \
    --steps 3000000 --variant recipe --span 1450000 2000000 --span 2050000 2500000 --span 2550000 3002944
# --per-seed: a curve, a table row and span means per variant and seed instead of their mean

python experiments/expert_learning.py --out runs/turn_batch14 --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast-3m --seeds 0 1 \
    --variant "batch16k-from-1.4M:steps_per_update=4096@0;16384@1.4M"
ln -sf ../turn_batch/batch16k-from-2M ../turn_batch_base/recipe runs/turn_batch14/   # one figure for all three
python experiments/expert_learning.py --out runs/turn_batch14 --replot --per-seed --snippets SYN_turn_left-0-182 \
    --steps 3000000 --variant recipe \
    --variant "batch16k-from-2M:steps_per_update=4096@0;16384@2M" \
    --span 1450000 2000000 --span 2050000 2500000 --span 2550000 3010000

# each kept expert over 1000 other episodes (the first 1000-episode score is final_evaluation in done.json)
for run in runs/turn_batch14/batch16k-from-1.4M/seed0 runs/turn_batch14/batch16k-from-1.4M/seed1 \
    runs/turn_batch/batch16k-from-2M/seed0 runs/turn_batch/batch16k-from-2M/seed1 runs/turn_batch_base/recipe/seed0; do
    mocap-hierarchy expert eval "$run/SYN_turn_left-0-182" --episodes 1000 --seed 1
done
