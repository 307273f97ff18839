#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-width-envs-termination.md:
# one change each from --profile fast on SYN_walk_slow-0-182 (16 environments, a termination curriculum,
# 2x512 and 3x1024 networks at 3e-4 and at smaller step sizes), 300k steps, one seed.
# Expected time: about 1.5-2 hours on a 2-core CPU machine (five runs of 8-22 minutes one at a time,
# then two runs of 18 and 28 minutes side by side, as measured beside other jobs).
set -euo pipefail
cd "$(dirname "$0")/.."

# The termination curriculum (termination_start, termination_curriculum_steps) was removed on 2026-11-26, so this
# experiment runs at commit 0e51b82, the last commit that had it: a git worktree of that commit in a temporary
# folder (added once), its code first on the Python path (the installed packages are the same; nothing new is
# installed), its own expert_learning.py and the flags of that time. The runs still go to this checkout's runs/.
source experiments/shared/library_at_0e51b82.sh
export PYTHONPATH="$OLD${PYTHONPATH:+:$PYTHONPATH}"

python "$OLD/experiments/expert_learning.py" --out runs/axes --snippets SYN_walk_slow-0-182 --steps 300000 \
    --eval-every 25000 --eval-episodes 50 --jobs 1 --profile fast --seeds 0 \
    --variant fast --variant "width2x512:hidden_layers=512;512" \
    --variant "termination0.6to0.3:termination_start=0.6,termination_curriculum_steps=300000" \
    --variant envs16:n_envs=16 --variant "width3x1024:hidden_layers=1024;1024;1024"
# then the widths again at smaller step sizes, two side by side, linked into runs/axes:
python "$OLD/experiments/expert_learning.py" --out runs/axes_width --snippets SYN_walk_slow-0-182 --steps 300000 \
    --eval-every 25000 --eval-episodes 50 --jobs 2 --profile fast --seeds 0 \
    --variant "width2x512-lr1.5e-4:hidden_layers=512;512,learning_rates=1.5e-4" \
    --variant "width3x1024-lr3e-5:hidden_layers=1024;1024;1024,learning_rates=3e-5"
ln -sf ../axes_width/width2x512-lr1.5e-4 ../axes_width/width3x1024-lr3e-5 runs/axes/
python "$OLD/experiments/expert_learning.py" --out runs/axes --replot --snippets SYN_walk_slow-0-182 --steps 300000 \
    --variant fast --variant "width2x512:hidden_layers=512;512" \
    --variant "termination0.6to0.3:termination_start=0.6,termination_curriculum_steps=300000" \
    --variant envs16:n_envs=16 --variant "width3x1024:hidden_layers=1024;1024;1024" \
    --variant "width2x512-lr1.5e-4:hidden_layers=512;512,learning_rates=1.5e-4" \
    --variant "width3x1024-lr3e-5:hidden_layers=1024;1024;1024,learning_rates=3e-5" \
    --span 25000 150000 --span 175000 303000
