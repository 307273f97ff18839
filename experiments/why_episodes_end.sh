#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-why-episodes-end.md:
# falls against drift at the end of each episode, 30 episodes per snippet, for the --profile fast experts
# in runs/long/fast/seed0 (from experiments/fast_profile_long_runs.sh) and their playback.
# Expected time: not recorded (evaluation only, minutes on a 2-core CPU machine).
set -euo pipefail
cd "$(dirname "$0")/.."

python experiments/episode_ends.py runs/long/fast/seed0 --playback --episodes 30
