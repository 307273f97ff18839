#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-longer-runs-3m.md:
# the step-size-1e-4 branches of the --profile fast runs to 3M on walk slow, turn left and walk fast,
# and their kept experts over the paper's 1000 episodes.
# Needs runs/long/fast/seed0 (experiments/fast_profile_long_runs.sh) and runs/branch
# (experiments/branches_600k.sh).
# Expected time: 5.6 h (walking) and 4.8 h (turning) of wall time as measured on a 2-core CPU machine
# with shared cores; fast walking not recorded.
set -euo pipefail
cd "$(dirname "$0")/.."

# the walking step-size branch to 3M (the branches command with only its variant)
python experiments/expert_learning.py --out runs/branch --snippets SYN_walk_slow-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast \
    --variant lr1e-4:learning_rate=1e-4,start_from=runs/long/fast/seed0
mkdir -p runs/eval1000
mocap-hierarchy expert eval runs/branch/lr1e-4/seed0/SYN_walk_slow-0-182 --episodes 1000 --json runs/eval1000/walk_slow_lr1e-4.json

# turning: both branches (the page's table reads them at 1.05-1.2M), then the step-size branch to 3M
python experiments/expert_learning.py --out runs/branch_turn --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant continued:start_from=runs/long/fast/seed0 \
    --variant lr1e-4:learning_rate=1e-4,start_from=runs/long/fast/seed0
python experiments/expert_learning.py --out runs/branch_turn --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast \
    --variant lr1e-4:learning_rate=1e-4,start_from=runs/long/fast/seed0
mocap-hierarchy expert eval runs/branch_turn/lr1e-4/seed0/SYN_turn_left-0-182 --episodes 1000

# fast walking: the same branch from its 926k checkpoint
python experiments/expert_learning.py --out runs/branch_more --snippets SYN_walk_fast-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast \
    --variant lr1e-4:learning_rate=1e-4,start_from=runs/long/fast/seed0
mocap-hierarchy expert eval runs/branch_more/lr1e-4/seed0/SYN_walk_fast-0-182 --episodes 1000
