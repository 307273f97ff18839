#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-go-to-target-2m.md: the approach_reward=10 runs resumed, decoder to 2M and
# joint targets to 1.5M.
# Expected time on a 2-core CPU machine: about 1.5 hours (67 minutes from 1M to 2M when measured).
# Needs the 1M runs of experiments/go_to_target_approach.sh and runs/gtt_1m from experiments/go_to_target_1m.sh.
set -euo pipefail
cd "$(dirname "$0")/.."

ppo=(--n-envs 8 --steps-per-update 4096 --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4
    --no-subprocess-envs --checkpoint-every 100000)
out=runs/gtt_approach/go_to_target

decoder_runs() {  # steps
    local pids=()
    for seed in 0 1 2; do
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v2 \
            --latent-prior synthetic-v2 --set approach_reward=10 \
            --out $out/decoder_v2_prior_approach10/seed$seed --seed $seed \
            --initial-std 1.0 --steps "$1" "${ppo[@]}" &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
}

# The 1M policies aside (the comparison without the term and the 1M rows read them).
for seed in 0 1 2; do
    mkdir -p runs/gtt_approach_1m/approach10/seed$seed
    cp $out/decoder_v2_prior_approach10/seed$seed/{policy.safetensors,transfer.json} runs/gtt_approach_1m/approach10/seed$seed/
done

decoder_runs 1500000 &
decoders=$!
pids=()
for seed in 0 1 2; do
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --set approach_reward=10 \
        --out $out/joints_approach10/seed$seed --seed $seed --steps 1500000 "${ppo[@]}" &
    pids+=($!)
done
wait "$decoders"
for pid in "${pids[@]}"; do wait "$pid"; done
python experiments/target_reaching.py $out/decoder_v2_prior_approach10/seed{0,1,2} $out/joints_approach10/seed{0,1,2} \
    --episodes 50

decoder_runs 2000000
for span in "--since 1000000 --until 1250000" "--since 1250000 --until 1500000" "--since 1500000 --until 1750000" \
    "--since 1750000" "--until 1500000"; do
    # shellcheck disable=SC2086
    python experiments/transfer_table.py $out/decoder_v2_prior_approach10 $out/joints_approach10 $span
done
python experiments/target_reaching.py $out/decoder_v2_prior_approach10/seed{0,1,2} \
    --episodes 50 --json runs/target_reaching_approach10_2m.json

# The three settings side by side: no term (to 1M), the term on the decoder (to 2M) and on joint targets (to 1.5M).
mkdir -p runs/gtt_compare_2m/go_to_target
cp -r runs/gtt_1m/go_to_target/decoder_v2_prior_std1 $out/decoder_v2_prior_approach10 $out/joints_approach10 \
    runs/gtt_compare_2m/go_to_target/
mocap-hierarchy report runs/gtt_compare_2m
cp runs/gtt_compare_2m/report/transfer_curves.png docs/figures/transfer_curves_gtt_approach.png
