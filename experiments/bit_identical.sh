#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-26-configs-bit-identical.md: the expert cases and the batched run
# trained with the library before the change (commit 0e51b82) and after it, then compared; and the
# quickstart at a quarter of its budget, before and after. Expected time: about 25 minutes on a 2-core
# CPU machine.
set -euo pipefail
cd "$(dirname "$0")/.."

# The library before the change, in a worktree of its own (the installed packages are the same).
source experiments/shared/library_at_0e51b82.sh

PYTHONPATH="$OLD" python experiments/bit_identical.py train-old runs/bit_identical/old
python experiments/bit_identical.py train-new runs/bit_identical/new
python experiments/bit_identical.py compare runs/bit_identical/old runs/bit_identical/new

PYTHONPATH="$OLD" python -m mocap_hierarchy.cli quickstart --scale 0.25 --out runs/bit_identical/quickstart_old
mocap-hierarchy quickstart --scale 0.25 --out runs/bit_identical/quickstart_new
python experiments/bit_identical.py compare runs/bit_identical/quickstart_old runs/bit_identical/quickstart_new
