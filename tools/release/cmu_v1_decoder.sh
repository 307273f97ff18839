#!/usr/bin/env bash
# The real release after its experts (tools/release/cmu_locomotion_v1_experts.sh has finished all 24): packages the
# experts as group cmu-locomotion-v1, rolls them out in the paper's layout, distils the multi-clip policy online with
# a learned prior (the recipe that kept the most of its experts under the noisy protocol and stood longest on its
# prior's samples on synthetic data: docs/experiments/2026-11-27-online-distillation.md), evaluates it on its own
# snippets (deterministic and the paper's noisy protocol) and on real snippets of trials it never saw, measures how
# long its prior's samples keep the humanoid up, and compares transfer on it against synthetic-v3 at equal steps
# (velocity control in any direction and go-to-target, three seeds each), and trains the task policies that ship on it
# (1M steps each). synthetic-v3's side of the comparison starts at once, at low priority, beside the rest; cmu-v1's
# side runs beside the shipped task policies.
# Resumable: rerun it after a kill; every finished step is skipped (each command resumes or its output exists); a
# step that fails stops the runs beside it. Where it stands: the files under runs/release-cmu-v1/ (dataset/,
# distill/, eval_*.json, transfer/, ship/). EXPERTS=DIR reads the experts from another folder (rehearsals).
# A rehearsal at tiny budgets, writing nothing into the package (about 10 minutes on 2 cores):
#   PARTIAL=1 OUT=/tmp/rehearsal PRETRAINED=/tmp/rehearsal/experts CARDS=/tmp/rehearsal/cards STEPS=20 \
#   TRANSFER_STEPS=4096 SHIP_STEPS=4096 ROLLOUTS="--n-start 1 --n-rsi 1" EPISODES=2 tools/release/cmu_v1_decoder.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
export OMP_NUM_THREADS=1
[ -z "${VIRTUAL_ENV:-}" ] && [ -f .venv/bin/activate ] && . .venv/bin/activate  # the README install
group=cmu-locomotion-v1
experts=${EXPERTS:-runs/release-cmu-v1/experts}
runs=${OUT:-runs/release-cmu-v1}
pretrained=${PRETRAINED:-distill/experts/pretrained/$group}
cards=${CARDS:-distill/experts/cards/$group}
ROLLOUTS=${ROLLOUTS:---n-start 20 --n-rsi 80}
EPISODES=${EPISODES:-50}
STEPS=${STEPS:-7700}            # distillation steps: synthetic-v3's 2,258 for 7 snippets, scaled to 24
TRANSFER_STEPS=${TRANSFER_STEPS:-300000}  # each run of the comparison against synthetic-v3
SHIP_STEPS=${SHIP_STEPS:-1000000}          # each task policy that ships

finished=$(ls $experts/*/done.json 2>/dev/null | wc -l)
if [ "$finished" -lt 24 ] && [ -z "${PARTIAL:-}" ]; then
    echo "$finished of 24 experts have finished: rerun tools/release/cmu_locomotion_v1_experts.sh first" \
        "(PARTIAL=1 goes on with the finished ones, for a rehearsal)" >&2
    exit 1
fi

# 0. Transfer at equal steps against synthetic-v3 (step 6), three seeds of each task: synthetic-v3's runs need none of
#    this release, so they start at once, beside steps 1-5, and take the time those leave a core idle.
transfer() {  # task label decoder prior seed [settings...]
    local task=$1 label=$2 decoder=$3 prior=$4 seed=$5
    shift 5
    mocap-hierarchy transfer train --task "$task" --decoder "$decoder" --latent-prior "$prior" \
        --out "${TRANSFER_ROOT:-$runs/transfer}/$task/$label/seed$seed" --seed "$seed" --initial-std 1.0 "$@" \
        --steps "$TRANSFER_STEPS" --n-envs 8 --steps-per-update 4096 --minibatch-size 512 \
        --hidden-layers 256 256 --learning-rate 3e-4 --no-subprocess-envs --checkpoint-every 100000
}
lane() {  # label decoder prior
    for seed in 0 1 2; do
        transfer velocity_control "$@" "$seed" --set max_speed=1.5
        transfer go_to_target "$@" "$seed" --set approach_reward=10
    done
}
(renice -n 10 -p $BASHPID > /dev/null; lane synthetic-v3 synthetic-v3 synthetic-v3) &  # at low priority: it waits
v3=$!
# A step that fails stops the lanes and their runs too (a rerun resumes them; two copies of a run never write at once).
trap 'for job in $(jobs -p); do pkill -P "$job"; kill "$job"; done 2> /dev/null || true' EXIT

# 1. The expert group: a card from each run, then the packaged directory (float16, pickle-free).
tools/release/package_experts.sh "$experts" "$pretrained" "$cards" $group

# 2. Their rollouts (the paper's A.2 layout), as for synthetic-v3: 20 episodes from the start, 80 from random frames.
# shellcheck disable=SC2086  # ROLLOUTS holds several flags
mocap-hierarchy rollout --experts "$pretrained" --out $runs/dataset $ROLLOUTS --workers 2

# 3. The multi-clip policy, online (the experts label the states it visits), with a learned prior.
mocap-hierarchy distill train --data $runs/dataset --out $runs/distill --online --experts "$pretrained" \
    --teacher-probability "linear:1@0,0@$((STEPS / 2))" --prior learned --steps "$STEPS" --batch-size 128 \
    --encoder-layers 512 512 --decoder-layers 512 512 512 --env-workers 2 --checkpoint-every 500

# 3b. The decoder as it ships (float16) with its learned prior bound to it: transfer trains on these, so the task
#     policies fit the shipped pair. The final card re-packages the same weights (same behaviour hash).
if [ ! -f $runs/packaged/cmu-v1-prior.safetensors ]; then
    mkdir -p $runs/packaged
    echo '{"name": "cmu-v1", "summary": "draft: the card with its scores comes with the release"}' \
        > $runs/packaged/draft.card.json
    mocap-hierarchy decoder package $runs/distill/decoder.safetensors $runs/packaged/cmu-v1.safetensors \
        --card $runs/packaged/draft.card.json --prior $runs/distill/prior.safetensors \
        --prior-out $runs/packaged/cmu-v1-prior.safetensors
fi

# 4. How well it tracks: its own snippets (fraction of the experts; deterministic, then the paper's noisy protocol),
#    then snippets of the library's trials none of whose snippets it was trained on.
[ -f $runs/eval_seen.json ] || mocap-hierarchy distill eval $runs/distill --data $runs/dataset --episodes "$EPISODES" \
    --json $runs/eval_seen.json
[ -f $runs/eval_seen_noisy.json ] || mocap-hierarchy distill eval $runs/distill --data $runs/dataset \
    --episodes "$EPISODES" --action-noise 0.1 --json $runs/eval_seen_noisy.json
trained=$(ls $experts | sed 's/-[0-9]*-[0-9]*$//' | sort -u)
unseen=$(mocap-hierarchy clips snippets --clips $group | grep -v -F -f <(printf '%s-\n' $trained))
[ -f $runs/eval_unseen.json ] || mocap-hierarchy distill eval $runs/distill --clips $group --snippets $unseen \
    --episodes "$EPISODES" --json $runs/eval_unseen.json

# 5. Standing on its own: the decoder driven by samples of its learned prior on go-to-target (goal: 300 steps).
[ -f $runs/prior_survival.json ] || python experiments/prior_survival.py $runs/distill --episodes "$EPISODES" \
    --json $runs/prior_survival.json

# 6. The same comparison on cmu-v1, one lane, beside the task policies that ship on it (step 7): seed 0 of each task
#    (chosen before any result), 1M steps, as synthetic-v3's were trained, one after the other on the other core.
lane cmu-v1 $runs/packaged/cmu-v1.safetensors $runs/packaged/cmu-v1-prior.safetensors &
real=$!
packaged="$runs/packaged/cmu-v1.safetensors $runs/packaged/cmu-v1-prior.safetensors"
# shellcheck disable=SC2086  # packaged holds the decoder and its prior
TRANSFER_ROOT=$runs/ship TRANSFER_STEPS=$SHIP_STEPS transfer velocity_control cmu-v1 $packaged 0 --set max_speed=1.5
# shellcheck disable=SC2086
TRANSFER_ROOT=$runs/ship TRANSFER_STEPS=$SHIP_STEPS transfer go_to_target cmu-v1 $packaged 0 --set approach_reward=10
wait $v3
wait $real
python experiments/transfer_table.py $runs/transfer/velocity_control
python experiments/transfer_table.py $runs/transfer/go_to_target
# Each run's deterministic evaluation: speed tracking (slope, heading cosine, standing still) and target reaching.
velocity_runs=$(ls -d $runs/transfer/velocity_control/*/seed*)
[ -f $runs/velocity_control_300k.json ] || python experiments/speed_tracking.py $velocity_runs --episodes 30 \
    --steps 1000 --out $runs/velocity_control_300k.png --json $runs/velocity_control_300k.json
[ -f $runs/go_to_target_300k.json ] || python experiments/target_reaching.py \
    $(ls -d $runs/transfer/go_to_target/*/seed*) --episodes 50 --json $runs/go_to_target_300k.json

# 7. The shipped task policies' evaluations, as their cards quote.
[ -f $runs/ship_velocity_control.json ] || python experiments/speed_tracking.py \
    $runs/ship/velocity_control/cmu-v1/seed0 --labels shipped --episodes 30 --steps 1000 \
    --out $runs/ship_velocity_control.png --json $runs/ship_velocity_control.json
[ -f $runs/ship_go_to_target.json ] || python experiments/target_reaching.py $runs/ship/go_to_target/cmu-v1/seed0 \
    --labels shipped --episodes 50 --json $runs/ship_go_to_target.json
# Every figure the results page quotes, in one file (docs/results/release_cmu_v1.json once the release ships).
python -m tools.release.release_results $runs --json $runs/release_results.json
echo "next: ship it with tools/release/cmu_v1_ship.sh (cards from these files, then packaging), and read the cards"
