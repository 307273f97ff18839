#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-go-to-target-lower-noise.md: go-to-target around the synthetic-v2 prior with
# initial std 0.3 against 1.0, two seeds x 500k.
# Expected time on a 2-core CPU machine: about 34 minutes (four runs side by side).
set -euo pipefail
cd "$(dirname "$0")/.."

pids=()
for std in 0.3 1; do
    for seed in 0 1; do
        folder=decoder_v2_prior_std$std
        if [ "$std" = 1 ]; then folder=decoder_v2_prior_std1; fi
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v2 \
            --latent-prior synthetic-v2 --out runs/gtt_std/go_to_target/$folder/seed$seed --seed $seed \
            --initial-std $std --steps 500000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
            --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
        pids+=($!)
    done
done
for pid in "${pids[@]}"; do wait "$pid"; done

python experiments/transfer_table.py runs/gtt_std
python experiments/transfer_table.py runs/gtt_std --since 250000
