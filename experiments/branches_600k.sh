#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-branches-600k.md:
# five one-change branches of the --profile fast SYN_walk_slow-0-182 run at 600k (runs/long/fast/seed0,
# from experiments/fast_profile_long_runs.sh stopped at about 600k steps).
# Expected time: not recorded; many hours on a 2-core CPU machine (the table reads the branches at
# 1.25-1.4M; stop with Ctrl-C there, rerunning resumes).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/expert_learning.py --out runs/branch --snippets SYN_walk_slow-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 4 --profile fast \
    --variant continued:start_from=runs/long/fast/seed0 \
    --variant gamma0.99:gamma=0.99,start_from=runs/long/fast/seed0 \
    --variant lr1e-4:learning_rate=1e-4,start_from=runs/long/fast/seed0 \
    --variant batch16k:steps_per_update=16384,start_from=runs/long/fast/seed0 \
    --variant std0.1:action_std=0.1,start_from=runs/long/fast/seed0
