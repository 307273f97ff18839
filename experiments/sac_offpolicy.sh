#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-sac-offpolicy.md:
# SAC (one gradient step per environment step) on --profile fast's task, SYN_walk_slow-0-182, 20k steps,
# against the PPO run runs/axes/fast (from experiments/width_envs_termination.sh).
# Expected time: about 23 minutes on a 2-core CPU machine (measured beside two other jobs).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/expert_offpolicy.py --out runs/offpolicy --steps 20000 --eval-every 5000 --eval-episodes 50 \
    --baseline runs/axes/fast/seed0/SYN_walk_slow-0-182
