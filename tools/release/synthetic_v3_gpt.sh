#!/usr/bin/env bash
# Trains the motion-completion GPT shipped as synthetic-v3 on the rollouts of the shipped experts of group
# synthetic-v3, measures its completions against the two baselines over many contexts, and packages it with its
# card (docs/guides/synthetic-release.md). About an hour of training on one core of a 2-core CPU machine.
# Resumable: rerun it after a kill; finished steps are skipped.
set -euo pipefail
cd "$(dirname "$0")/../.."
export OMP_NUM_THREADS=1
data=runs/rebuild-v3/dataset   # the same rollouts the decoder rebuild distils (one command, resumable)
out=runs/release-v3/gpt
mocap-hierarchy rollout --experts synthetic-v3 --out $data --n-start 20 --n-rsi 80 --workers 2
mocap-hierarchy gpt train --data $data --out $out --steps 14000 --layers 3 --heads 6 --embedding-size 192 \
    --batch-size 64 --learning-rate 3e-4 --checkpoint-every 500
[ -f $out/completion.json ] || mocap-hierarchy gpt complete --gpt $out --experts synthetic-v3 --episodes 20 \
    --json $out/completion.json
mocap-hierarchy gpt package $out distill/gpt/pretrained/synthetic-v3.safetensors \
    --card distill/gpt/cards/synthetic-v3.card.json --scores $out/completion.json
