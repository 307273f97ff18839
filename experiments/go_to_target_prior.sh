#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-go-to-target-prior.md: go-to-target on synthetic-v2 with and without its
# latent prior, initial std 1.0, three seeds x 300k.
# Expected time on a 2-core CPU machine: about 50 minutes (six runs side by side).
set -euo pipefail
cd "$(dirname "$0")/.."

pids=()
for seed in 0 1 2; do
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v2 \
        --latent-prior synthetic-v2 --out runs/gtt_prior/go_to_target/decoder_v2_prior_std1/seed$seed --seed $seed \
        --initial-std 1.0 --steps 300000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
        --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
    pids+=($!)
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v2 \
        --out runs/gtt_prior/go_to_target/decoder_v2_plain_std1/seed$seed --seed $seed \
        --initial-std 1.0 --steps 300000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
        --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
    pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done

python experiments/transfer_table.py runs/gtt_prior
mocap-hierarchy report runs/gtt_prior
cp runs/gtt_prior/report/transfer_curves.png docs/figures/transfer_curves_gtt_prior.png
