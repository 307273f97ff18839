#!/usr/bin/env bash
# Ships the real release once tools/release/cmu_v1_decoder.sh has finished (its last step writes
# runs/release-cmu-v1/release_results.json): packages the expert group again from its runs, writes the cards of the decoder and its prior, the multi-clip policy and
# the task policies from the runs' files (python -m tools.release.release_cards), then packages, each with its card:
# the decoder cmu-v1 (float16) with its learned prior bound to it, the multi-clip policy cmu-v1 (float16, refused if
# that changes an action by more than 0.002), and the task policies on cmu-v1 that follow their commands (TASKS
# names others: velocity control follows with a speed slope >= 0.5 and more reward per step than standing still,
# go-to-target with a heading cosine >= 0.5).
# Last, the release's figures go where the results page quotes them (docs/results/release_cmu_v1.json).
# Read the cards it wrote before committing; after editing one, rerun this script: every file is written again from
# the same runs (same weights, new card). Nothing is trained or downloaded; about 3 minutes of CPU.
# DEST=DIR writes under another folder than the repository (a rehearsal; EXPERTS=DIR and EXPERT_CARDS=DIR name the
# expert runs and their cards):
#   OUT=/tmp/rehearsal DEST=/tmp/ship tools/release/cmu_v1_ship.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
[ -z "${VIRTUAL_ENV:-}" ] && [ -f .venv/bin/activate ] && . .venv/bin/activate  # the README install
runs=${OUT:-runs/release-cmu-v1}
dest=${DEST:-.}
name=cmu-v1
results=$runs/release_results.json
if [ ! -f "$results" ]; then
    echo "$results is missing: run tools/release/cmu_v1_decoder.sh to its end first (it writes that file last)" >&2
    exit 1
fi

# 0. The expert group again from its runs, with the same cards (same weights; harmless to repeat): the files packaged
#    before experts recorded their library's name in their provenance carry the path of its cached clip file.
AGAIN=1 tools/release/package_experts.sh "${EXPERTS:-runs/release-cmu-v1/experts}" \
    "$dest/distill/experts/pretrained/cmu-locomotion-v1" "${EXPERT_CARDS:-distill/experts/cards/cmu-locomotion-v1}" \
    cmu-locomotion-v1

# 1. The cards, every figure read from the runs' files.
python -m tools.release.release_cards "$runs" --decoder $name --root "$dest" ${EXPERT_CARDS:+--expert-cards "$EXPERT_CARDS"}
cards=$dest/hierarchy/pretrained/cards

# 2. The decoder with its prior (the same float16 weights the task policies trained on), then the whole policy.
mkdir -p "$dest/hierarchy/pretrained/priors" "$dest/distill/npmp/pretrained"
mocap-hierarchy decoder package "$runs/distill/decoder.safetensors" "$dest/hierarchy/pretrained/$name.safetensors" \
    --card "$cards/$name.card.json" --scores "$runs/eval_seen_noisy.json" --prior "$runs/distill/prior.safetensors" \
    --prior-out "$dest/hierarchy/pretrained/priors/$name.safetensors"
mocap-hierarchy distill package "$runs/distill" "$dest/distill/npmp/pretrained/$name.safetensors" \
    --card "$dest/distill/npmp/cards/$name.card.json" --scores "$runs/eval_seen_noisy.json"

# 3. The task policies that ship, after the decoder so that they name it: those that follow their commands
#    (release_results.py: velocity control's speed slope >= 0.5 and more reward per step than standing still;
#    go-to-target's heading cosine >= 0.5), or the TASKS given. A task that does not ship loses its card.
following=$(python -c 'import json, sys
shipped = json.load(open(sys.argv[1]))["shipped"]
print(" ".join(task for task, figures in shipped.items() if figures["follows_commands"]))' "$results")
mkdir -p "$dest/hierarchy/pretrained/policies/$name"
for task in velocity_control go_to_target; do
    case " ${TASKS:-$following} " in
    *" $task "*)
        mocap-hierarchy transfer package "$runs/ship/$task/$name/seed0" \
            "$dest/hierarchy/pretrained/policies/$name/$task.safetensors" \
            --card "$cards/policies/$name/$task.card.json" ;;
    *)
        echo "the $task policy on $name does not ship, nor its card (${TASKS:+TASKS leaves it out}${TASKS:-it does not follow its commands})"
        rm -f "$cards/policies/$name/$task.card.json" ;;
    esac
done

# 4. The figures the results page quotes, and its quotes of them rewritten.
mkdir -p "$dest/docs/results"
cp "$results" "$dest/docs/results/release_cmu_v1.json"
[ "$dest" = . ] && python tools/quoted_values.py docs/results/release_cmu_v1.json  # the pages' quotes of it
echo "shipped under $dest: read the cards (git diff), then the checklist 'Shipping it' of docs/guides/real-release.md"
