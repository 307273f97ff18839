#!/usr/bin/env bash
# Does a longer distillation keep the real decoder up longer on its prior? The real release's distillation
# (runs/release-cmu-v1/distill, 7,700 steps: the decoder cmu-v1 and its learned prior) continued with nothing else
# changed, to 1.5x and 2x its steps (the trainer resumes exactly; its steps may grow), each decoder and prior then
# driven by its prior's samples and mean on go-to-target (experiments/prior_survival.py, 50 episodes, cap 600),
# the release's own run measured again beside them, and each multi-clip policy tracking its 24 snippets under the
# paper's noisy protocol (distill eval, 50 episodes each; the release's own is runs/release-cmu-v1's
# eval_seen_noisy.json). Writes docs/results/prior_longer_distillation.json.
# Needs the release's runs (tools/release/cmu_v1_decoder.sh). Expected time on a 2-core CPU machine: about 55
# minutes per 3,850 steps (the release's pace), then a minute per survival measure. Resumable: rerun it after a kill.
set -euo pipefail
cd "$(dirname "$0")/.."
export OMP_NUM_THREADS=1
release=runs/release-cmu-v1
out=runs/prior-longer
# The run records its teachers by path and file hash. The shipped expert files were repackaged after it (the same
# weights, other provenance), so it continues in a scratch copy of this checkout whose expert group is the one it
# was distilled from (commit 3ba2235), with runs/ linked back here.
scratch=$out/checkout
if [ ! -d $scratch ]; then
    mkdir -p $out && rm -rf $out/partial-checkout && mkdir $out/partial-checkout
    git archive HEAD | tar -x -C $out/partial-checkout
    rm -r $out/partial-checkout/distill/experts/pretrained/cmu-locomotion-v1
    git archive 3ba2235 distill/experts/pretrained/cmu-locomotion-v1 | tar -x -C $out/partial-checkout
    ln -s "$PWD/runs" $out/partial-checkout/runs
    mv $out/partial-checkout $scratch
fi
experts=distill/experts/pretrained/cmu-locomotion-v1
from=$release/distill
for steps in 11550 15400; do
    # each length starts from a copy of the one before (the release's for the first); a finished run trains nothing
    if [ ! -d $out/distill-$steps ]; then
        mkdir -p $out && rm -rf $out/partial && cp -r $from $out/partial && mv $out/partial $out/distill-$steps
    fi
    (cd $scratch && python -m mocap_hierarchy distill train --data $release/dataset --out $out/distill-$steps \
        --online --experts $experts --teacher-probability "linear:1@0,0@3850" --prior learned --steps $steps --batch-size 128 \
        --encoder-layers 512 512 --decoder-layers 512 512 512 --env-workers "${ENV_WORKERS:-2}" \
        --checkpoint-every 500)
    from=$out/distill-$steps
done
for steps in 11550 15400; do
    [ -f $out/eval_noisy-$steps.json ] || mocap-hierarchy distill eval $out/distill-$steps --data $release/dataset \
        --episodes 50 --action-noise 0.1 --json $out/eval_noisy-$steps.json
done
[ -f $out/survival.json ] || python experiments/prior_survival.py $release/distill $out/distill-11550 \
    $out/distill-15400 --episodes 50 --json $out/survival.json
python - "$release" "$out" <<'PY'
import json, sys
from pathlib import Path

release, out = (Path(arg) for arg in sys.argv[1:])
survival = json.loads((out / "survival.json").read_text())["runs"]
runs = {7700: (release / "distill", release / "eval_seen_noisy.json")}
runs |= {steps: (out / f"distill-{steps}", out / f"eval_noisy-{steps}.json") for steps in (11550, 15400)}
summary = {}
for steps, (folder, evaluation) in runs.items():
    tracked = json.loads(evaluation.read_text())
    up = survival[str(folder)]
    summary[str(steps)] = {
        "survival_samples": round(up["samples_steps"], 1),
        "survival_mean": round(up["mean_steps"], 1),
        "speed_samples": round(up["samples_speed"], 2),
        "noisy_fraction_reward": round(tracked["fraction"]["normalized_reward"], 3),
        "noisy_success": round(tracked["over_snippets"]["success"]["mean"], 3),
        "noisy_global_position_error_mm": round(tracked["over_snippets"]["global_position_error_mm"]["mean"], 1),
    }
document = {"summary": summary, "survival": survival}
Path("docs/results/prior_longer_distillation.json").write_text(json.dumps(document, indent=2) + "\n")
print(json.dumps(summary, indent=2))
PY
