#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-tracking-metrics.md and the results page's tracking-metrics table:
# our trackers in PHC's columns (success, G-MPJPE, ...) under PHC's protocol and the paper's.
# Expected time on a 2-core CPU machine: the quickstart 10 minutes; two --profile fast-3m-wide experts about
# 70 minutes with the cores to themselves (stand 300k steps, walk slow 1.5M); their rollouts 20 s, the distillation
# about 15 minutes; the evaluations a minute or two each.
set -euo pipefail
cd "$(dirname "$0")/.."

# 1. What a newcomer's main job trains: three small experts and a multi-clip policy distilled from them.
mocap-hierarchy quickstart --out runs/tracking_metrics/quickstart
python experiments/tracking_metrics.py --experts runs/tracking_metrics/quickstart/experts \
    --policy runs/tracking_metrics/quickstart/distill/policy.safetensors \
    --expert-label quickstart_experts --policy-label quickstart_policy --episodes 100 \
    --out docs/results/tracking_metrics_quickstart.json

# 2. Experts trained with the profile behind synthetic-v3, on two of its snippets.
mocap-hierarchy expert train --snippet SYN_stand-0-181 --profile fast-3m-wide --steps 300000 --eval-every 100000 \
    --eval-episodes 50 --final-eval-episodes 200 --out runs/tracking_metrics/experts
mocap-hierarchy expert train --snippet SYN_walk_slow-0-182 --profile fast-3m-wide --steps 1500000 --eval-every 100000 \
    --eval-episodes 50 --final-eval-episodes 200 --out runs/tracking_metrics/experts
# 3. A multi-clip policy distilled from those two with synthetic-v3's distillation settings (about 15 minutes).
mocap-hierarchy rollout --experts runs/tracking_metrics/experts --out runs/tracking_metrics/dataset \
    --n-start 20 --n-rsi 80 --workers 2
mocap-hierarchy distill train --data runs/tracking_metrics/dataset --out runs/tracking_metrics/distill --steps 2258 \
    --batch-size 128 --encoder-layers 512 512 --decoder-layers 512 512 512
python experiments/tracking_metrics.py --experts runs/tracking_metrics/experts --expert-label wide_experts \
    --policy runs/tracking_metrics/distill/policy.safetensors --policy-label wide_policy \
    --episodes 100 --out docs/results/tracking_metrics_wide.json
