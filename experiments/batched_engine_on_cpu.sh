#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-batched-engine-on-cpu.md: parity of the batched MuJoCo Warp engine with the
# CPU tracking env, and its speed on Warp's CPU device (not a GPU figure).
# Needs the gpu extra: pip install -c requirements.lock -e ".[gpu]"
# Expected time: not recorded; compiling Warp's kernels the first time takes about 2 minutes on 2 cores (cached).
set -euo pipefail
cd "$(dirname "$0")/.."

pytest tests/tasks/test_batched_tracking.py
python benchmarks/warp_speed.py --device cpu --worlds 1 4 16 64 --steps 5 --ppo
