#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-v3-go-to-target-approach.md: go-to-target with approach_reward=10 around the
# synthetic-v3 prior, three seeds to 500k (policies set aside) and on to 1M.
# Expected time on a 2-core CPU machine: about 1.7 hours (65 minutes to 500k, 35 from 500k to 1M, three side by side
# beside other runs when measured).
set -euo pipefail
cd "$(dirname "$0")/.."

folder=runs/gtt_v3/go_to_target/decoder_v3_prior_approach10
train() {  # steps
    local pids=()
    for seed in 0 1 2; do
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v3 \
            --latent-prior synthetic-v3 --set approach_reward=10 \
            --out $folder/seed$seed --seed $seed \
            --initial-std 1.0 --steps "$1" --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
            --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000 &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
}

train 500000
for seed in 0 1 2; do
    mkdir -p runs/gtt_v3_500k/seed$seed
    cp $folder/seed$seed/{policy.safetensors,transfer.json} runs/gtt_v3_500k/seed$seed/
done
python experiments/target_reaching.py runs/gtt_v3_500k/seed{0,1,2} --episodes 50

train 1000000
for span in "--until 250000" "--since 250000 --until 500000" "--since 500000 --until 750000" "--since 750000"; do
    # shellcheck disable=SC2086
    python experiments/transfer_table.py runs/gtt_v3 $span
done
mocap-hierarchy report runs/gtt_v3
cp runs/gtt_v3/report/transfer_curves.png docs/figures/transfer_curves_gtt_v3.png
python experiments/target_reaching.py $folder/seed{0,1,2} --episodes 50 --json runs/target_reaching_v3_1m.json \
    --prior-alone synthetic-v3
