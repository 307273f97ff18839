#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-21-quickstart-experts.md:
# the quickstart's three 16k-step experts scored with the paper's protocol (100 episodes each),
# with and without action noise.
# Expected time: about 9 minutes for the quickstart on a 2-core CPU machine, then a few minutes of evaluation.
set -euo pipefail
cd "$(dirname "$0")/.."

mocap-hierarchy quickstart                                                        # runs/quickstart/
mocap-hierarchy expert eval runs/quickstart/experts --episodes 100                  # stochastic (noise 0.1)
mocap-hierarchy expert eval runs/quickstart/experts --episodes 100 --deterministic
