#!/usr/bin/env bash
# Does a student that acts with the paper's action noise during online collection hold up better under the
# noisy protocol? (docs/experiments/2026-11-27-student-noise.md). One change against learned-online of
# experiments/online_distillation.sh: --student-noise 0.1 (the student's actions during collection carry the
# noise the noisy protocol adds). It did not help and the setting was removed: that arm runs the library at
# commit fe34e6b (experiments/shared/library_at_fe34e6b.sh). Three trainer seeds; the baseline's runs are rebuilt first if missing
# (distillation is deterministic: a rebuilt run equals the one measured) and evaluated again with the same
# protocols: 50 episodes from random frames, deterministic and with noise 0.1; whole clips; samples of the prior.
# Time on a 2-core CPU machine, measured 2026-11-27: 70 minutes for the three distillations side by side beside two
# PPO runs, then about 10 minutes of evaluations. Resumable: rerun it after a kill.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=shared/evaluate_distillation.sh
source experiments/shared/evaluate_distillation.sh
# shellcheck source=shared/library_at_fe34e6b.sh
source experiments/shared/library_at_fe34e6b.sh
data=runs/rebuild-v3/dataset
out=runs/online
[ -d $data ] || bash experiments/decoder_rebuild_spread.sh  # the shipped experts' rollouts
card=(--steps 2258 --batch-size 128 --encoder-layers 512 512 --decoder-layers 512 512 512 --prior learned)
online=(--online --experts synthetic-v3 --teacher-probability linear:1@0,0@1000)
distill() {  # folder seed [extra flags...]
    local folder=$1 seed=$2
    shift 2
    OMP_NUM_THREADS=1 mocap-hierarchy distill train --data $data --out "$folder" "${card[@]}" --seed "$seed" \
        "${online[@]}" "$@" >"$folder.log" 2>&1
}
seed_lane() {  # seed: the baseline (kept when finished), then the change
    distill $out/learned-online-seed$1 "$1"
    PYTHONPATH="$OLD_NOISE" distill $out/learned-online-noisy-seed$1 "$1" --student-noise 0.1
}
mkdir -p $out
seed_lane 0 &
seed_lane 1 &
seed_lane 2 &
wait
runs=() folders=()
for seed in 0 1 2; do
    runs+=(learned-online=$out/learned-online-seed$seed learned-online-noisy=$out/learned-online-noisy-seed$seed)
done
for run in "${runs[@]}"; do folders+=("${run#*=}"); done
evaluate_distillation $data "${folders[@]}"
python experiments/prior_survival.py "${folders[@]}" --episodes 20 --limit 600 --json $out/survival-student-noise.json
python experiments/online_distillation.py "${runs[@]}" --survival $out/survival-student-noise.json \
    --json docs/results/student_noise.json --figure docs/figures/student_noise.png
