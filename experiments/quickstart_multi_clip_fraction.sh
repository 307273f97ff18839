#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-21-quickstart-multi-clip-fraction.md: the quickstart's multi-clip policy
# as a fraction of its experts (deterministic, from the snippet start, 10 episodes per snippet).
# Expected time: about 10 minutes for the quickstart on a 2-core machine, plus a minute or two of evaluation.
set -euo pipefail
cd "$(dirname "$0")/.."

mocap-hierarchy quickstart --out runs/quickstart
mocap-hierarchy distill eval runs/quickstart/distill/policy.safetensors --init start --episodes 10 \
    --snippets SYN_squat-0-155 SYN_walk_slow-0-182 SYN_wave-0-196
mocap-hierarchy expert eval runs/quickstart/experts --episodes 10 --init start --deterministic
