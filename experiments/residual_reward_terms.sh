#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-residual-reward-terms.md:
# the CoMic reward's terms per step for playback, the residual and the absolute expert of runs/recipe_obs
# (20 episodes each, the paper's protocol), then playback without action noise.
# Needs runs/recipe_obs from experiments/step_size_action_mode_observations.sh.
# Expected time: not recorded (evaluation only, minutes on a 2-core CPU machine).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/reward_terms.py runs/recipe_obs/residual-refobs-std0.3/seed0/SYN_walk_slow-0-182 --playback
python experiments/reward_terms.py runs/recipe_obs/absolute-refobs-std0.3/seed0/SYN_walk_slow-0-182
# playback's joint-velocity term with and without action noise (10 episodes each)
python experiments/reward_terms.py runs/recipe_obs/residual-refobs-std0.3/seed0/SYN_walk_slow-0-182 --playback --episodes 10
python experiments/reward_terms.py runs/recipe_obs/residual-refobs-std0.3/seed0/SYN_walk_slow-0-182 --playback --episodes 10 --action-noise 0
