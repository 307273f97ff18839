#!/usr/bin/env bash
# Rehearses, on this machine, what the device calls do with the staged parts: a Python 3.12
# environment standing in for a GPU node's (the packages it has that the staged site leans on:
# torch 2.11 as there, numpy, scipy, h5py and the rest at the lock's versions), the parts joined and
# checked, the site unpacked first on the path, then tools/device/rehearsal_check.py (every staged
# package imports under 3.12, Warp starts, the CPU tracking env steps, MuJoCo Warp steps the walker on
# Warp's CPU device) and tools/device/run.py --rehearsal (every check of the device run, tiny, on
# Warp's CPU device, from the unpacked site).
#
# Usage: bash tools/device/rehearse.sh [STAGED]   (STAGED: a stage.py --for rehearsal output,
#        default .stage/rehearsal; the stand-in environment is kept in /tmp/mh-rehearsal-venv and
#        takes a few minutes the first time: the registry's torch for 3.12 is its CUDA build, about
#        3 GB with its libraries; results under /tmp/mh-rehearsal-out)
set -euo pipefail
cd "$(dirname "$0")/../.."
STAGED="${1:-.stage/rehearsal}"
PYTHON="${PYTHON312:-$(ls -d "$HOME"/.pyenv/versions/3.12*/bin/python3.12 2>/dev/null | tail -1)}"
VENV=/tmp/mh-rehearsal-venv
SITE=/tmp/mh-rehearsal-site

if [ ! -x "$VENV/bin/python" ]; then
    "$PYTHON" -m venv "$VENV"
    # What a GPU node has and the staged packages import (its own versions may differ a little).
    "$VENV/bin/python" -m pip install --quiet --root-user-action=ignore \
        numpy==2.4.6 scipy==1.17.1 lxml==6.1.3 absl-py==2.5.1 protobuf==5.29.6 pyparsing==3.3.3 \
        requests==2.34.2 tqdm==4.70.1 h5py==3.16.0 safetensors==0.8.0 cloudpickle==3.1.2 packaging==26.3 \
        typing_extensions==4.16.0 PyYAML==6.0.3 pandas matplotlib onnx onnxscript tensorboard
    # A GPU node's torch (2.11 here); the lock's pin (2.13) is for this machine's Python 3.11.
    PIP_CONSTRAINT=/dev/null "$VENV/bin/python" -m pip install --quiet --root-user-action=ignore torch==2.11.0
fi

started=$(date +%s)
"$VENV/bin/python" tools/device/parts.py join --manifest "$STAGED/parts/manifest.json" --out /tmp/mh-site.tar.xz
rm -rf "$SITE" && mkdir -p "$SITE"
tar -xJf /tmp/mh-site.tar.xz -C "$SITE"
echo "joined, checked and unpacked in $(( $(date +%s) - started )) s: $(du -sh "$SITE" | cut -f1)"
PYTHONPATH="$SITE:$PWD" "$VENV/bin/python" tools/device/rehearsal_check.py
"$VENV/bin/python" tools/device/run.py --staged "$STAGED" --out /tmp/mh-rehearsal-out --rehearsal --device cpu \
    --budget-seconds 300 --commit "$(git rev-parse HEAD)"
