#!/usr/bin/env bash
# Reproduces the decoder rebuild of docs/guides/synthetic-release.md at full size, three times: the shipped experts'
# rollouts once, then the distillation on synthetic-v3's card with three trainer seeds, each evaluated with the
# paper's protocol (50 episodes per snippet from random frames); rebuild_spread.py compares them with the shipped
# decoder's card and writes docs/results/rebuild_v3.json.
# Expected time on a 2-core CPU machine: rollouts about a minute, each distillation about 20 minutes, each
# evaluation about a minute. Resumable: rerun it after a kill.
set -euo pipefail
cd "$(dirname "$0")/.."
out=runs/rebuild-v3
mocap-hierarchy rollout --experts synthetic-v3 --out $out/dataset --n-start 20 --n-rsi 80 --workers 2
for seed in 0 1 2; do
    mocap-hierarchy distill train --data $out/dataset --out $out/distill-seed$seed --steps 2258 \
        --batch-size 128 --encoder-layers 512 512 --decoder-layers 512 512 512 --seed $seed
    [ -f $out/eval-seed$seed.json ] || mocap-hierarchy distill eval $out/distill-seed$seed --data $out/dataset \
        --episodes 50 --json $out/eval-seed$seed.json
done
python experiments/rebuild_spread.py $out/eval-seed0.json $out/eval-seed1.json $out/eval-seed2.json \
    --json docs/results/rebuild_v3.json
