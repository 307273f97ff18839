#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-29-prior-start-states.md: the shipped decoders cmu-v1 and synthetic-v3, each
# driven by its shipped latent prior on go-to-target, from the task's standing start and from poses of its own
# training snippets (48 episodes per setting); writes docs/results/prior_start_states.json.
# Expected time on a 2-core CPU machine: under 2 minutes. Deterministic: a rerun writes the same file.
set -euo pipefail
cd "$(dirname "$0")/.."
OMP_NUM_THREADS=1 python experiments/prior_start_states.py --episodes 48 --limit 600 \
    --json docs/results/prior_start_states.json
