#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-fast-profile-long-runs.md:
# --profile fast on SYN_walk_slow-0-182, SYN_wave-0-196 and SYN_turn_left-0-182 (3M budget, evaluations
# every 50k over 50 episodes), a learned-noise run on walk slow, the report, and the wave expert over
# 1000 episodes.
# Expected time: about 45 minutes to 350k steps per job with four jobs on a 2-core CPU machine; the page's
# table stops at 550-650k steps (stop with Ctrl-C; rerunning resumes). The full 3M budget takes many hours.
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/expert_learning.py --out runs/long --snippets SYN_walk_slow-0-182 SYN_wave-0-196 \
    SYN_turn_left-0-182 --steps 3000000 --eval-every 50000 --eval-episodes 50 --jobs 4 --profile fast \
    --variant fast
python experiments/expert_learning.py --out runs/long --snippets SYN_walk_slow-0-182 --steps 3000000 \
    --eval-every 50000 --eval-episodes 50 --jobs 1 --profile fast --variant fast-learnstd:learn_action_std=true
mocap-hierarchy report runs/long --out docs/figures/report_fast_profile
mocap-hierarchy expert eval runs/long/fast/seed0/SYN_wave-0-196 --episodes 1000
