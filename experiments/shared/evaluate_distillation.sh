# Sourced by the distillation experiments: evaluate_distillation DATA FOLDER... writes, beside each distillation
# folder, what experiments/online_distillation.py reads (skipped where already written): eval.json (50 episodes
# from random frames of the training snippets, deterministic), eval-noisy.json (the same with the paper's action
# noise 0.1) and eval-clips.json (20 episodes of each whole synthetic clip).
evaluate_distillation() {
    local data=$1 folder
    shift
    local clips=(SYN_stand SYN_turn_left SYN_turn_right SYN_walk_backward SYN_walk_fast SYN_walk_slow SYN_wave)
    for folder in "$@"; do
        [ -f "$folder/eval.json" ] || mocap-hierarchy distill eval "$folder" --data "$data" --episodes 50 \
            --json "$folder/eval.json"
        [ -f "$folder/eval-noisy.json" ] || mocap-hierarchy distill eval "$folder" --data "$data" --episodes 50 \
            --action-noise 0.1 --json "$folder/eval-noisy.json"
        [ -f "$folder/eval-clips.json" ] || mocap-hierarchy distill eval "$folder" --snippets "${clips[@]}" \
            --episodes 20 --json "$folder/eval-clips.json"
    done
}
