#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-quickstart-spread.md: the quickstart's figures over seeds 0, 1 and 2,
# summarised as mean, standard deviation and range.
# Expected time: about 10 minutes per quickstart on a 2-core machine, so about 30 minutes in all.
# Note: today's quickstart runs velocity control on the shipped decoder synthetic-v3 (131072 steps per run),
# so the velocity-control rows differ from the page's, which ran on the quickstart's own decoder.
set -euo pipefail
cd "$(dirname "$0")/.."

for s in 0 1 2; do mocap-hierarchy quickstart --out runs/seed$s --seed $s; done
python experiments/quickstart_spread.py runs/seed0 runs/seed1 runs/seed2
