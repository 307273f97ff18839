#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-28-real-expert-budgets.md: the real release's expert runs read by kind of
# motion (steps to 0.9 of the snippet, final length over 1000 episodes) and their curves.
# Expected time: the experts' script runs for hours of CPU (tools/release/cmu_locomotion_v1_experts.sh, two lanes
# on 2 cores, resumable); reading the runs takes seconds. With the runs already there, only the reading runs.
set -euo pipefail
cd "$(dirname "$0")/.."

NEXT=0 tools/release/cmu_locomotion_v1_experts.sh  # trains or resumes the 24 experts; finished ones are skipped
python experiments/real_expert_budgets.py runs/release-cmu-v1/experts --out docs/figures/real_expert_budgets.png \
    --json runs/release-cmu-v1/expert_budgets.json
