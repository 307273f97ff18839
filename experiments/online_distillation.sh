#!/usr/bin/env bash
# Online against offline distillation (docs/experiments/2026-11-27-online-distillation.md): the multi-clip
# policy distilled from the shipped experts' rollouts, four ways, three trainer seeds each, at synthetic-v3's
# card budget (2,258 steps of 128 windows, encoder 2 x 512, decoder 3 x 512):
#   offline          the paper's recipe (the decoder rebuild's runs, experiments/decoder_rebuild_spread.sh)
#   online           half of each batch from the student's own states, labelled by the experts (--online;
#                    the teacher drives whole episodes with a probability going from 1 to 0 by step 1000)
#   learned          offline, with a learned state-conditioned prior in the KL term (--prior learned)
#   learned-online   both
# Each is evaluated on the training snippets (50 episodes from random frames, deterministic and with the
# paper's action noise 0.1), on the whole clips (20 episodes each) and by how long its decoder, driven by
# samples of its prior, keeps the humanoid up on go-to-target (20 episodes, cap 600 steps).
# Expected time on a 2-core CPU machine: about 20 minutes per distillation (one core each), 3 minutes of
# evaluation per run. Resumable: rerun it after a kill.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=shared/evaluate_distillation.sh
source experiments/shared/evaluate_distillation.sh
data=runs/rebuild-v3/dataset
out=runs/online
bash experiments/decoder_rebuild_spread.sh  # the dataset and the offline runs
card=(--steps 2258 --batch-size 128 --encoder-layers 512 512 --decoder-layers 512 512 512)
online=(--online --experts synthetic-v3 --teacher-probability linear:1@0,0@1000)
runs=()
for seed in 0 1 2; do
    mocap-hierarchy distill train --data $data --out $out/online-seed$seed "${card[@]}" --seed $seed "${online[@]}"
    mocap-hierarchy distill train --data $data --out $out/learned-offline-seed$seed "${card[@]}" --seed $seed \
        --prior learned
    mocap-hierarchy distill train --data $data --out $out/learned-online-seed$seed "${card[@]}" --seed $seed \
        --prior learned "${online[@]}"
    runs+=(offline=runs/rebuild-v3/distill-seed$seed online=$out/online-seed$seed
        learned=$out/learned-offline-seed$seed learned-online=$out/learned-online-seed$seed)
done
folders=()
for run in "${runs[@]}"; do folders+=("${run#*=}"); done
evaluate_distillation $data "${folders[@]}"
python experiments/prior_survival.py "${folders[@]}" --episodes 20 --limit 600 --json $out/survival.json
python experiments/online_distillation.py "${runs[@]}" --survival $out/survival.json \
    --json docs/results/online_distillation.json --figure docs/figures/online_distillation.png
