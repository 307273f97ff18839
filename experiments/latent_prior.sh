#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-24-latent-prior.md: the synthetic-v2 latent prior (fit, balance), velocity
# control around it (commands to 1.5 m/s in any direction, initial std 1.0 and 0.5, three seeds x 300k) and its
# overhead in the loop.
# Expected time on a 2-core CPU machine: about an hour (prior 74 s; three runs side by side take about 25 minutes).
# Needs runs/synthetic-v2 (bash experiments/decoder_synthetic_v2.sh) for the fit; the runs use the result, which has
# the bytes of the shipped synthetic-v2 prior.
set -euo pipefail
cd "$(dirname "$0")/.."

OMP_NUM_THREADS=1 mocap-hierarchy decoder fit-prior runs/synthetic-v2/distill/policy.safetensors synthetic-v2 \
    runs/prior/synthetic-v2.safetensors --data runs/synthetic-v2/dataset
python experiments/decoder_balance.py --decoder synthetic-v2 --latent-prior runs/prior/synthetic-v2.safetensors \
    --stds 0 0.3 0.5 1.0 --steps-per-latent 1

for std in 1.0 0.5; do
    pids=()
    for seed in 0 1 2; do
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-v2 \
            --latent-prior runs/prior/synthetic-v2.safetensors \
            --out runs/transfer_speed/velocity_control/decoder_v2_prior_std$std/seed$seed --seed $seed --initial-std $std \
            --set max_speed=1.5 --steps 300000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
            --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
done

# The v2, prior and joint-target runs side by side for the figure.
mkdir -p runs/prior_cmp
for setting in decoder_v2_std1 decoder_v2_prior_std1.0 decoder_v2_prior_std0.5 joints; do
    if [ -d "runs/transfer_speed/velocity_control/$setting" ]; then
        mkdir -p runs/prior_cmp/velocity_control
        cp -r "runs/transfer_speed/velocity_control/$setting" runs/prior_cmp/velocity_control/
    fi
done
mocap-hierarchy report runs/prior_cmp
cp runs/prior_cmp/report/transfer_curves.png docs/figures/transfer_curves_prior.png
for setting in decoder_v2_prior_std1.0 decoder_v2_prior_std0.5; do
    python experiments/speed_tracking.py runs/transfer_speed/velocity_control/$setting/seed0 \
        runs/transfer_speed/velocity_control/$setting/seed1 --episodes 30 --out runs/transfer_speed/speed_tracking_$setting.png
done

python benchmarks/latent_overhead.py --torch-threads 1
python benchmarks/latent_overhead.py --torch-threads 1 --latent-prior
