#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-go-to-target-1m.md: go-to-target on synthetic-v2 to 1M, three seeds around
# its latent prior and seed 0 on plain latents, initial std 1.0.
# Expected time on a 2-core CPU machine: about 43 minutes (four runs side by side).
set -euo pipefail
cd "$(dirname "$0")/.."

pids=()
for seed in 0 1 2; do
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v2 \
        --latent-prior synthetic-v2 --out runs/gtt_1m/go_to_target/decoder_v2_prior_std1/seed$seed --seed $seed \
        --initial-std 1.0 --steps 1000000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
        --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
    pids+=($!)
done
OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v2 \
    --out runs/gtt_1m/go_to_target/decoder_v2_plain_std1/seed0 --seed 0 \
    --initial-std 1.0 --steps 1000000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
    --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
pids+=($!)
for pid in "${pids[@]}"; do wait "$pid"; done

python experiments/transfer_table.py runs/gtt_1m --until 250000
python experiments/transfer_table.py runs/gtt_1m --since 250000 --until 500000
python experiments/transfer_table.py runs/gtt_1m --since 500000 --until 750000
python experiments/transfer_table.py runs/gtt_1m --since 750000
mocap-hierarchy report runs/gtt_1m --out runs/report_gtt_1m
cp runs/report_gtt_1m/transfer_curves.png docs/figures/transfer_curves_gtt_1m.png
