#!/usr/bin/env bash
# Packages the finished expert runs of a folder as a shipped group (float16, pickle-free), each with its card: the
# card is written from the run's files where it is missing (tools/release/expert_card.py), the expert where it is not
# packaged yet, or again where AGAIN=1 (same weights; the card and provenance written anew).
# Usage: tools/release/package_experts.sh RUNS PRETRAINED CARDS GROUP
#   RUNS        one run folder per snippet (those without done.json are skipped)
#   PRETRAINED  where the group's packaged experts go (distill/experts/pretrained/GROUP to ship it)
#   CARDS       the group's cards (distill/experts/cards/GROUP)
#   GROUP       the group's name, also the shipped clip library its experts recorded
set -euo pipefail
if [ $# -ne 4 ]; then
    echo "usage: $0 RUNS PRETRAINED CARDS GROUP (AGAIN=1 packages the packaged ones again)" >&2
    exit 2
fi
runs=$1 pretrained=$2 cards=$3 group=$4
for run in "$runs"/*/; do
    snippet=$(basename "$run")
    [ -f "$run/done.json" ] || continue
    card=$cards/$snippet.card.json
    [ -f "$card" ] || python "$(dirname "$0")/expert_card.py" "$run" --group "$group" --clips "$group" --out "$card"
    if [ -n "${AGAIN:-}" ] || [ ! -d "$pretrained/$snippet" ]; then
        mocap-hierarchy expert package "$run" "$pretrained" --card "$card" --clips "$group"
    fi
done
