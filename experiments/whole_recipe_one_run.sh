#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-whole-recipe-one-run.md:
# the recipe (--profile fast with 3e-4 then 1e-4 from 600k and noise 0.3 then 0.2 from 2M, i.e. what is now
# --profile fast-3m) on SYN_turn_left-0-182 and SYN_walk_fast-0-182, against its 2M state continued with
# noise 0.3. As measured the folders were copied at 2M to runs/snapshots/recipe2M/seed0/; this script keeps
# a snapshot at 2M instead (snapshot_steps changes nothing in training) and branches with branch_step.
# Expected time: 71-73 minutes to 2M per run on one core each of a 2-core CPU machine, then 1M more steps
# for each of the four runs sharing the two cores (not recorded).
set -euo pipefail
cd "$(dirname "$0")/.."

# Branching from a snapshot (snapshot_steps, branch_step) was removed on 2026-11-26, so this experiment runs at
# commit 0e51b82, the last commit that had it: a git worktree of that commit in a temporary folder (added once),
# its code first on the Python path (the installed packages are the same; nothing new is installed), its own
# expert_learning.py and the flags of that time. The runs still go to this checkout's runs/.
source experiments/shared/library_at_0e51b82.sh
export PYTHONPATH="$OLD${PYTHONPATH:+:$PYTHONPATH}"

python "$OLD/experiments/expert_learning.py" --out runs/recipe --snippets SYN_turn_left-0-182 SYN_walk_fast-0-182 \
    --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant "recipe:learning_rates=3e-4;1e-4,learning_rate_steps=600000,action_std_steps=2000000,later_action_stds=0.2,snapshot_steps=2000000"
# the baseline: the recipe's 2M state continued with noise 0.3
python "$OLD/experiments/expert_learning.py" --out runs/recipe --snippets SYN_turn_left-0-182 SYN_walk_fast-0-182 \
    --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 2 --profile fast \
    --variant continued:learning_rates=1e-4,branch_from=runs/recipe/recipe/seed0,branch_step=2000000
python "$OLD/experiments/expert_learning.py" --out runs/recipe --replot --snippets SYN_turn_left-0-182 --steps 3000000
python "$OLD/experiments/expert_learning.py" --out runs/recipe --replot --snippets SYN_walk_fast-0-182 --steps 3000000
