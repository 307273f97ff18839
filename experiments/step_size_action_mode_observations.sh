#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-step-size-action-mode-observations.md:
# two sweeps of one-change variants on SYN_walk_slow-0-182 (step size and action mode; reference
# observations and training noise), 200k steps per run, evaluated every 25k over 50 episodes.
# Expected time: not recorded (12 runs of 200k steps, two at a time, on a 2-core CPU machine).
# Rerunning the same command resumes; add --replot to redraw only.
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/expert_learning.py --out runs/recipe_lr --snippets SYN_walk_slow-0-182 --steps 200000 \
    --eval-every 25000 --eval-episodes 50 --jobs 2 \
    --base hidden_layers=256,256 learning_rate=3e-4 steps_per_update=4096 epochs=5 n_envs=2 \
    --variant absolute-lr3e-4 --variant residual-lr3e-4:residual_actions=true \
    --variant absolute-lr1e-4:learning_rate=1e-4 --variant absolute-lr3e-5:learning_rate=3e-5 \
    --variant absolute-adaptive:schedule=adaptive --variant residual-adaptive:schedule=adaptive,residual_actions=true
python experiments/expert_learning.py --out runs/recipe_obs --snippets SYN_walk_slow-0-182 --steps 200000 \
    --eval-every 25000 --eval-episodes 50 --jobs 2 \
    --base hidden_layers=256,256 learning_rate=3e-4 steps_per_update=4096 epochs=5 n_envs=2 \
    --variant absolute --variant residual:residual_actions=true \
    --variant absolute-refobs:reference_observations=true \
    --variant residual-refobs:residual_actions=true,reference_observations=true \
    --variant absolute-refobs-std0.3:reference_observations=true,action_std=0.3 \
    --variant residual-refobs-std0.3:residual_actions=true,reference_observations=true,action_std=0.3
