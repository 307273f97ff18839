#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-27-v4-candidate-transfer.md: transfer at equal steps on the decoder distilled
# online with a learned prior (runs/online/learned-online-seed0, from experiments/online_distillation.sh) against
# synthetic-v3: velocity control in any direction, then go-to-target on dm_control's reward alone, 300k steps each,
# the two decoders side by side (one per core).
# Time on a 2-core CPU machine, measured 2026-11-27: 90 minutes beside three distillations (a run of 300k steps took
# about 6 minutes while the two lanes had the machine to themselves).
set -euo pipefail
cd "$(dirname "$0")/.."

candidate=runs/online/learned-online-seed0
seeds=${SEEDS:-0 1 2}
train() {  # task label decoder prior seed [extra settings...]
    local task=$1 label=$2 decoder=$3 prior=$4 seed=$5
    shift 5
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task "$task" --decoder "$decoder" --latent-prior "$prior" \
        --out "runs/v4_candidate/$task/$label/seed$seed" --seed "$seed" --initial-std 1.0 "$@" \
        --steps 300000 --n-envs 8 --steps-per-update 4096 --minibatch-size 512 --hidden-layers 256 256 \
        --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000
}
lane() {  # label decoder prior
    for seed in $seeds; do
        train velocity_control "$@" "$seed" --set max_speed=1.5
        train go_to_target "$@" "$seed"
    done
}

lane decoder_v3_prior synthetic-v3 synthetic-v3 &
v3=$!
lane decoder_learned_online $candidate/decoder.safetensors $candidate/prior.safetensors &
candidate_lane=$!
wait $v3
wait $candidate_lane

python experiments/transfer_table.py runs/v4_candidate/velocity_control
python experiments/transfer_table.py runs/v4_candidate/go_to_target
mocap-hierarchy report runs/v4_candidate
cp runs/v4_candidate/report/transfer_curves.png docs/figures/transfer_curves_v4_candidate.png
labels=("v3 seed 0" "v3 seed 1" "v3 seed 2" "candidate seed 0" "candidate seed 1" "candidate seed 2")
for task in velocity_control go_to_target; do
    folders=(runs/v4_candidate/$task/{decoder_v3_prior,decoder_learned_online}/seed{0,1,2})
    if [ $task = velocity_control ]; then
        python experiments/speed_tracking.py "${folders[@]}" --episodes 30 --labels "${labels[@]}" \
            --out docs/figures/speed_tracking_v4_candidate.png --json runs/v4_candidate/speed_tracking.json
    else
        python experiments/target_reaching.py "${folders[@]}" --episodes 50 --labels "${labels[@]}" \
            --json runs/v4_candidate/target_reaching.json
    fi
done
