#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-25-go-to-target-approach.md: go-to-target with approach_reward=10 (to 1M) and 1
# (to 500k) around the synthetic-v2 prior, and approach_reward=10 on joint targets (to 1M), three seeds each.
# Expected time on a 2-core CPU machine: about 2.5 hours (25-29 minutes per 500k steps with three or four runs side
# by side; the joint-target runs 41 minutes to 1M, three side by side).
# Needs runs/gtt_1m from experiments/go_to_target_1m.sh for the rows without the term.
set -euo pipefail
cd "$(dirname "$0")/.."

ppo=(--n-envs 8 --steps-per-update 4096 --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4
    --no-subprocess-envs --checkpoint-every 100000)
out=runs/gtt_approach/go_to_target

approach_runs() {  # weight steps seeds...
    local weight=$1 steps=$2 pids=()
    shift 2
    for seed in "$@"; do
        OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --decoder synthetic-v2 \
            --latent-prior synthetic-v2 --set approach_reward=$weight \
            --out $out/decoder_v2_prior_approach$weight/seed$seed --seed $seed \
            --initial-std 1.0 --steps $steps "${ppo[@]}" &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do wait "$pid"; done
}

# To 500k: weight 10 (seeds 0-2) and weight 1 (seeds 0-2); the weight-10 policies at 500k are set aside.
approach_runs 10 500000 0 1 2
approach_runs 1 500000 0 1 2
for seed in 0 1 2; do
    mkdir -p runs/gtt_approach_500k/approach10/seed$seed
    cp $out/decoder_v2_prior_approach10/seed$seed/{policy.safetensors,transfer.json} runs/gtt_approach_500k/approach10/seed$seed/
done
python experiments/target_reaching.py runs/gtt_approach_500k/approach10/seed{0,1,2} \
    $out/decoder_v2_prior_approach1/seed{0,1,2} --episodes 50

# Weight 10 on to 1M; then the joint-target runs.
approach_runs 10 1000000 0 1 2
pids=()
for seed in 0 1 2; do
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task go_to_target --set approach_reward=10 \
        --out $out/joints_approach10/seed$seed --seed $seed --steps 1000000 "${ppo[@]}" &
    pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done

for span in "--until 250000" "--since 250000 --until 500000" "--since 500000 --until 750000" "--since 750000"; do
    # shellcheck disable=SC2086
    python experiments/transfer_table.py runs/gtt_1m $out/decoder_v2_prior_approach10 $out/decoder_v2_prior_approach1 \
        $out/joints_approach10 $span
done
python experiments/target_reaching.py $out/decoder_v2_prior_approach10/seed{0,1,2} \
    runs/gtt_1m/go_to_target/decoder_v2_prior_std1/seed{0,1,2} --episodes 50 --prior-alone synthetic-v2
python experiments/target_reaching.py $out/joints_approach10/seed{0,1,2} --episodes 50
