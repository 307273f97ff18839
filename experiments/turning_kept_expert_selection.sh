#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-turning-kept-expert-selection.md:
# seed 1 of --profile fast-3m with 16,384 steps per update from 2M, again with 500-episode evaluations from 2M
# and a snapshot at 2M; a branch of that snapshot with 32,768 steps per update; the per-seed replot against
# runs/turn_batch/batch16k-from-2M (from experiments/turning_larger_updates_within_3m.sh).
# Expected time: 94 minutes for the run from scratch and 44 for the branch (measured side by side on a
# 2-core CPU machine; here they run one after the other).
set -euo pipefail
cd "$(dirname "$0")/.."

# Branching from a snapshot (snapshot_steps, branch_step) was removed on 2026-11-26, so this experiment runs at
# commit 0e51b82, the last commit that had it: a git worktree of that commit in a temporary folder (added once),
# its code first on the Python path (the installed packages are the same; nothing new is installed), its own
# expert_learning.py and the flags of that time. The runs still go to this checkout's runs/.
source experiments/shared/library_at_0e51b82.sh
export PYTHONPATH="$OLD${PYTHONPATH:+:$PYTHONPATH}"

python "$OLD/experiments/expert_learning.py" --out runs/turn_select --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m --seeds 1 \
    --variant "batch16k-from-2M-eval500:steps_per_update_steps=2000000,later_steps_per_update=16384,eval_episodes_steps=2000000,later_eval_episodes=500,snapshot_steps=2000000"
python "$OLD/experiments/expert_learning.py" --out runs/turn_select32k --snippets SYN_turn_left-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast-3m --seeds 1 \
    --variant "batch32k-from-2M-eval500:steps_per_update_steps=2000000,later_steps_per_update=32768,eval_episodes_steps=2000000,later_eval_episodes=500,branch_from=runs/turn_select/batch16k-from-2M-eval500/seed1,branch_step=2000000"
ln -sf ../turn_select32k/batch32k-from-2M-eval500 ../turn_batch/batch16k-from-2M runs/turn_select/
python "$OLD/experiments/expert_learning.py" --out runs/turn_select --replot --per-seed --snippets SYN_turn_left-0-182 \
    --steps 3000000 --seeds 1 --variant "batch16k-from-2M:steps_per_update_steps=2000000,later_steps_per_update=16384" \
    --variant "batch32k-from-2M-eval500:steps_per_update_steps=2000000,later_steps_per_update=32768,eval_episodes_steps=2000000,later_eval_episodes=500" \
    --span 2050000 2500000 --span 2550000 3020000
# the kept expert over two more sets of 1000 episodes (evaluation seeds 0 and 1)
mocap-hierarchy expert eval runs/turn_select/batch16k-from-2M-eval500/seed1/SYN_turn_left-0-182 --episodes 1000
mocap-hierarchy expert eval runs/turn_select/batch16k-from-2M-eval500/seed1/SYN_turn_left-0-182 --episodes 1000 --seed 1
