#!/usr/bin/env bash
# Reproduces docs/experiments/2026-11-23-expert-training-time.md:
# py-spy samples of one short training run per process layout (2 envs in worker processes, 2, 8 and 16 in the
# trainer's process), then the end-to-end rates of four layouts, interleaved over two trials.
# Needs py-spy on the path. Expected time: not recorded (minutes per command on a 2-core CPU machine).
set -euo pipefail
cd "$(dirname "$0")/.."

python benchmarks/expert_profile.py --steps 30000 --n-envs 2
python benchmarks/expert_profile.py --steps 30000 --n-envs 2 --in-process
python benchmarks/expert_profile.py --steps 30000 --n-envs 8 --in-process
python benchmarks/expert_profile.py --steps 30000 --n-envs 16 --in-process
python benchmarks/expert_throughput.py
