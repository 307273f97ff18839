#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-v3-straight-ahead-300k.md: velocity control with commands straight ahead
# around each decoder's prior, synthetic-v3 (three seeds) against synthetic-v2 (seed 0), 300k; then the quickstart.
# Expected time on a 2-core CPU machine: about 35 minutes (19 minutes for the four runs side by side, a few for the
# speed tracking, 12.9 minutes for the quickstart).
set -euo pipefail
cd "$(dirname "$0")/.."

run() {  # decoder seed
    OMP_NUM_THREADS=1 mocap-hierarchy transfer train --task velocity_control --decoder synthetic-$1 \
        --latent-prior synthetic-$1 --out runs/forward_v3/velocity_control/decoder_$1_prior/seed$2 --seed $2 \
        --initial-std 1.0 --set max_speed=1.5 heading_spread=0 --steps 300000 --n-envs 8 --steps-per-update 4096 \
        --minibatch-size 512 --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs \
        --checkpoint-every 100000
}
pids=()
for seed in 0 1 2; do run v3 $seed & pids+=($!); done
run v2 0 & pids+=($!)
for pid in "${pids[@]}"; do wait "$pid"; done

python experiments/transfer_table.py runs/forward_v3
mocap-hierarchy report runs/forward_v3
cp runs/forward_v3/report/transfer_curves.png docs/figures/transfer_curves_forward_v3.png
python experiments/speed_tracking.py runs/forward_v3/velocity_control/decoder_v3_prior/seed{0,1,2} \
    runs/forward_v3/velocity_control/decoder_v2_prior/seed0 --episodes 30 \
    --labels "v3 seed 0" "v3 seed 1" "v3 seed 2" "v2 seed 0" --out docs/figures/speed_tracking_forward_v3.png

mocap-hierarchy quickstart --out runs/quickstart_v3
