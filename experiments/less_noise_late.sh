#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-less-noise-late.md:
# the recipe (--profile fast, 3e-4 then 1e-4 from 600k) from scratch on SYN_walk_slow-0-182 to 3M, and four
# one-change branches of its 2M state to 3M (unchanged, step size 3e-5, 16,384 steps per update, noise 0.2).
# As measured the run was stopped just past 2M and its folder copied to runs/snapshots/walk2M/ for the
# branches; this script keeps a snapshot at 2M instead (snapshot_steps changes nothing in training) and
# branches from it with branch_step.
# Expected time: 97 minutes for the run from scratch to 3M (65 to 2M) on a 2-core CPU machine beside one
# other job; then the four branches, two at a time (not recorded).
set -euo pipefail
cd "$(dirname "$0")/.."

# Branching from a snapshot (snapshot_steps, branch_step) was removed on 2026-11-26, so this experiment runs at
# commit 0e51b82, the last commit that had it: a git worktree of that commit in a temporary folder (added once),
# its code first on the Python path (the installed packages are the same; nothing new is installed), its own
# expert_learning.py and the flags of that time. The runs still go to this checkout's runs/.
source experiments/shared/library_at_0e51b82.sh
export PYTHONPATH="$OLD${PYTHONPATH:+:$PYTHONPATH}"

python "$OLD/experiments/expert_learning.py" --out runs/late --snippets SYN_walk_slow-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast \
    --variant "two-phase:learning_rates=3e-4;1e-4,learning_rate_steps=600000,snapshot_steps=2000000"
python "$OLD/experiments/expert_learning.py" --out runs/late_branch --snippets SYN_walk_slow-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant continued:learning_rates=1e-4,branch_from=runs/late/two-phase/seed0,branch_step=2000000 \
    --variant lr3e-5:learning_rates=3e-5,branch_from=runs/late/two-phase/seed0,branch_step=2000000 \
    --variant batch16k:learning_rates=1e-4,steps_per_update=16384,branch_from=runs/late/two-phase/seed0,branch_step=2000000 \
    --variant std0.2:learning_rates=1e-4,action_std=0.2,branch_from=runs/late/two-phase/seed0,branch_step=2000000
# each kept expert's 1000-episode score: final_evaluation in runs/late_branch/VARIANT/seed0/SYN_walk_slow-0-182/done.json
