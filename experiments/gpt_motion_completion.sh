#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-21-gpt-motion-completion.md: a small GPT (430,520 parameters) trained on the
# quickstart's dataset, then motion completion after a 32-step expert prompt, with the cache and with
# MoCapAct's recompute window.
# Expected time: training 3.0 minutes on 2 cores, plus the completions; the quickstart first if runs/quickstart
# does not exist yet (about 10 minutes on a 2-core machine).
set -euo pipefail
cd "$(dirname "$0")/.."

[ -f runs/quickstart/summary.json ] || mocap-hierarchy quickstart --out runs/quickstart
mocap-hierarchy gpt train --data runs/quickstart/dataset --out runs/gpt --steps 3000 --layers 2 --heads 4 \
    --embedding-size 128 --batch-size 64 --learning-rate 3e-4
# The measure of 2026-11-21: the GPT alone, every episode from the snippet's first frame.
mocap-hierarchy gpt complete --gpt runs/gpt --experts runs/quickstart/experts --episodes 10 --completers gpt --starts 1
mocap-hierarchy gpt complete --gpt runs/gpt --experts runs/quickstart/experts --episodes 10 --completers gpt --starts 1 \
    --context window
