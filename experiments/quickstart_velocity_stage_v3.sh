#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-quickstart-velocity-stage-v3.md: the quickstart's velocity-control stage
# on the shipped decoder synthetic-v3 (around its latent prior) against joint targets, 131072 steps each.
# Expected time: 12.9 minutes when measured on a 2-core machine (a benchmark shared the cores for 3 minutes).
set -euo pipefail
cd "$(dirname "$0")/.."

mocap-hierarchy quickstart --out runs/quickstart
