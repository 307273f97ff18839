"""Drive the humanoid with an exported decoder alone: onnxruntime and numpy, no torch.

Export a decoder to one ONNX graph, then run it::

    mocap-hierarchy decoder export synthetic-v3 --onnx decoder.onnx
    python examples/onnx_decoder.py decoder.onnx --steps 300

The graph's metadata says which observation keys it reads, in which order, and the latent's size
and bound; this script reads them from the file, feeds the graph the task's raw observations and a
slowly drifting random latent, applies its action and starts a new episode when the walker falls.
A high-level policy would choose the latent instead (see the deployment guide).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import onnxruntime

import tasks


def open_decoder(path: str) -> tuple[onnxruntime.InferenceSession, list[str], int, float]:
    """The graph, its observation keys in input order, the latent size and the latent bound."""
    session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])
    interface = json.loads(session.get_modelmeta().custom_metadata_map["interface"])
    observation, latent = interface["inputs"]
    return session, [entry["key"] for entry in observation["keys"]], latent["shape"][1], latent["bound"]


def flat(observation: dict[str, np.ndarray], keys: list[str]) -> np.ndarray:
    """The raw observation as the graph's ``(1, observation_size)`` float32 input."""
    return np.concatenate([np.asarray(observation[key], np.float32).reshape(-1) for key in keys])[None]


def main(argv: list[str] | None = None) -> None:
    """Runs the walker on the decoder's graph for ``--steps`` control steps and prints how long it stayed up."""
    parser = argparse.ArgumentParser(description="Drive the humanoid with an exported decoder alone.")
    parser.add_argument("onnx", help="the decoder's ONNX file (`mocap-hierarchy decoder export`)")
    parser.add_argument("--steps", type=int, default=300, help="control steps to run (default: 300)")
    parser.add_argument("--task", default="velocity_control", help="registered task the walker stands in")
    parser.add_argument("--drift", type=float, default=0.3, help="standard deviation of the wandering latent (0: z=0)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the episodes and the latent")
    args = parser.parse_args(argv)

    session, keys, latent_size, bound = open_decoder(args.onnx)
    env = tasks.make(args.task)
    rng = np.random.default_rng(args.seed)
    z = np.zeros((1, latent_size), np.float32)
    observation, _ = env.reset(seed=args.seed)
    lengths, length, falls = [], 0, 0
    start = time.perf_counter()
    for _ in range(args.steps):
        wander = args.drift * np.sqrt(1 - 0.95**2) * rng.standard_normal(z.shape)  # keeps z's spread at --drift
        z = np.clip(0.95 * z + wander, -bound, bound).astype(np.float32)
        action = np.asarray(session.run(None, {"observation": flat(observation, keys), "latent": z})[0])[0]
        observation, _, terminated, truncated, info = env.step(action)  # within [-1, 1]: the graph clips
        length += 1
        if terminated or truncated:
            falls += bool(info.get("fell"))
            lengths.append(length)
            observation, _ = env.reset(seed=int(rng.integers(2**31)))
            length = 0
    seconds = time.perf_counter() - start
    lengths.append(length)  # the episode still running
    print(
        f"{args.steps} control steps in {seconds:.1f} s: {len(lengths)} episodes, {falls} falls, steps survived "
        f"per episode {lengths} (longest {max(lengths)})"
    )
    print(f"torch imported: {'torch' in sys.modules}")
    assert "torch" not in sys.modules, "the deployed decoder must run without torch"


if __name__ == "__main__":
    main()
