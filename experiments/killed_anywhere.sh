#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-killed-anywhere.md: SIGKILL at random moments into every long job,
# rerun until it finishes, outputs checked against an uninterrupted run.
# Expected time: not recorded (tiny budgets, seconds per job, nine jobs; the slow trials run too).
# Writes one row per job to kills.md.
set -euo pipefail
cd "$(dirname "$0")/.."

KILL_REPORT=kills.md pytest -m "slow or not slow" tests/distill/test_kill_resume.py tests/test_download.py -k killed
