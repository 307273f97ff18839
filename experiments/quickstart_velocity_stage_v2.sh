#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-quickstart-velocity-stage-v2.md: the quickstart's velocity-control stage
# on the shipped decoder synthetic-v2 (around its latent prior) against joint targets, 131072 steps each.
# Expected time: about 10 minutes on an idle 2-core machine (31.4 minutes when measured, with two other trainings
# sharing the cores).
# On 2026-11-25 synthetic-v2 was the quickstart's default decoder; today it is synthetic-v3, hence the flag.
set -euo pipefail
cd "$(dirname "$0")/.."

mocap-hierarchy quickstart --out runs/quickstart_v2 --transfer-decoder synthetic-v2
