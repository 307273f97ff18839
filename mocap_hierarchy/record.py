"""``mocap-hierarchy record`` and ``view``: any task, driven by any policy file, into a rerun recording.

What ``--policy`` may be (recognised by its content, never by unpickling):

* ``random``: uniform random actions in the task's action space;
* an expert directory (``clip_info.json`` inside) or a shipped expert's name
  (``synthetic-v3/SYN_walk_slow-0-182``): its deterministic actions, on the
  tracking or motion-completion task of its snippet, on the clip library it
  records (unless ``--set clips=...`` names other clips);
* a multi-clip ``policy.safetensors`` (``distill train``) or a shipped multi-clip
  policy's name (``cmu-v1``): tracking with its reference look-ahead and
  deterministic latents;
* a task ``policy.safetensors`` (``transfer train``) or a shipped task policy's
  name (``synthetic-v3/velocity_control``): its task, through its decoder when it
  has one (the latent ``z`` is recorded too);
* a ``decoder.safetensors`` or a shipped decoder's name: random latents through the decoder;
* a ``gpt.safetensors``: motion completion, prompted by ``--prompt EXPERT_DIR`` (or an expert's name).

A name several kinds share goes to the first of :data:`distill.catalogue.POLICY_KINDS` (a decoder
first), except on the tracking task, where a multi-clip policy comes before the decoder of its name
(:data:`distill.catalogue.TRACKING_POLICY_KINDS`): it tracks the clip, where the decoder would act at random.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import tasks
from distill.catalogue import POLICY_HINT_KINDS, POLICY_KINDS, TRACKING_POLICY_KINDS, catalogue
from foundation.described_file import METADATA_KEY
from foundation.shipped import Entry

Act = Callable[[dict[str, np.ndarray]], np.ndarray]
Rollout = tuple[gym.Env, Act, Callable[[], None] | None]
"""An environment, ``act(observation) -> action``, and what to run after each reset (or None)."""
TRACKING_TASKS = ("tracking", "tracking_expert", "motion_completion")
KIND_FORMATS = {
    "decoder": "decoder",
    "multi-clip policy": "multi_clip_policy",
    "task policy": "task_policy",
    "expert": "expert",
}
"""The file format each kind of shipped policy has; an expert group has none (record refuses it as a folder)."""


def policy_entry(policy: str, task: str | None = None) -> Entry | None:
    """What the shipped name ``policy`` is (:data:`distill.catalogue.POLICY_KINDS`, first wins), or None.

    On ``task`` ``tracking`` the kinds are tried in :data:`distill.catalogue.TRACKING_POLICY_KINDS` order (a
    multi-clip policy before the decoder of its name). None too when ``policy`` is an existing path, which
    always wins over a name.
    """
    kinds = TRACKING_POLICY_KINDS if task == "tracking" else POLICY_KINDS
    return None if Path(policy).exists() else catalogue().lookup(policy, kinds)


def file_format(path: Path) -> str:
    """``random``, ``expert`` or the ``format`` named inside a safetensors file."""
    if str(path) == "random":
        return "random"
    if path.is_dir() and (path / "clip_info.json").is_file():
        return "expert"
    if not path.exists():
        raise FileNotFoundError(
            f"policy {path} does not exist (give a file, an expert directory, 'random' or a shipped name; "
            f"{catalogue().hint(*POLICY_HINT_KINDS)})"
        )
    if path.is_dir():
        raise ValueError(f"{path} is a folder but not an expert directory; name the .safetensors file inside it")
    from safetensors import safe_open

    try:
        with safe_open(str(path), framework="pt") as f:
            description = json.loads((f.metadata() or {}).get(METADATA_KEY, "{}"))
    except Exception as error:
        raise ValueError(f"{path} is not a mocap-hierarchy policy file ({error})") from None
    found = description.get("format") if isinstance(description, dict) else None
    if not found or not isinstance(found, str):
        raise ValueError(f"{path} is a safetensors file without a mocap-hierarchy description (or a damaged one)")
    return found.removeprefix("mocap_hierarchy.")


def build_rollout(
    task: str, policy: str, overrides: dict[str, Any] | None = None, prompt: str | None = None, seed: int = 0
) -> Rollout:
    """The environment, the ``act(observation) -> action`` function and the reset hook a recording uses.

    Raises:
        ValueError: A policy that cannot drive ``task``, with what would.
    """
    overrides = dict(overrides or {})
    entry = policy_entry(policy, task)  # looked up once: an existing path, else a shipped name, else as given
    path = entry.path if entry else Path(policy)
    kind = (entry and KIND_FORMATS.get(entry.kind)) or file_format(path)
    if kind == "random":
        env = tasks.make(task, **overrides)
        env.action_space.seed(seed)
        return env, lambda observation: env.action_space.sample(), None
    if kind == "expert":
        return _expert(task, path, overrides)
    if kind == "multi_clip_policy":
        return _multi_clip(task, path, overrides)
    if kind == "task_policy":
        return _task_policy(task, path, overrides)
    if kind == "decoder":
        from hierarchy import LatentActionEnv, load_decoder

        env = LatentActionEnv(tasks.make(task, **overrides), load_decoder(path))
        env.action_space.seed(seed)
        return env, lambda observation: env.action_space.sample(), None
    if kind == "motion_gpt":
        return _gpt(task, path, overrides, prompt)
    raise ValueError(f"{path} holds a {kind!r} file, which is not a policy")


def _require_task(task: str, allowed: tuple[str, ...], what: str) -> None:
    if task not in allowed:
        raise ValueError(f"{what} drives the tasks {', '.join(allowed)}, not {task!r}")


def _batched(observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: v[None] for k, v in observation.items()}


def _single(prompt, env: gym.Env) -> Rollout:
    """A batched prompt policy (:mod:`distill.gpt.completion`) driving one environment."""
    unwrapped = env.unwrapped
    return env, lambda observation: prompt.act(_batched(observation), [unwrapped], [0])[0], lambda: prompt.reset(0)


def _expert(task: str, path: Path, overrides: dict[str, Any]) -> Rollout:
    from distill.experts.loading import load_expert
    from distill.gpt.completion import ExpertPrompt

    _require_task(task, TRACKING_TASKS, "an expert")
    prompt = ExpertPrompt(load_expert(path))  # makes residual actions absolute itself
    settings = {"snippets": (str(prompt.expert.spec.snippet),), **_recorded_clips(path)}
    return _single(prompt, tasks.make(task, **{**settings, **overrides}))


def _recorded_clips(expert: str | os.PathLike) -> dict[str, str]:
    """``{"clips": NAME}`` when ``expert`` records the clip library it was trained on, else nothing."""
    from distill.experts.clip_library import experts_clips

    clips = experts_clips([expert])
    return {} if clips is None else {"clips": clips}


def _multi_clip(task: str, path: Path, overrides: dict[str, Any]) -> Rollout:
    from distill.npmp.model import MultiClipPrompt
    from distill.npmp.policy_file import load_policy

    _require_task(task, ("tracking",), "the multi-clip policy")
    prompt = MultiClipPrompt(load_policy(path), rows=1)
    return _single(prompt, tasks.make(task, **{"ref_steps": prompt.ref_steps, "observables": prompt.keys, **overrides}))


def _task_policy(task: str, path: Path, overrides: dict[str, Any]) -> Rollout:
    from hierarchy.transfer import policy_env

    policy, env = policy_env(path, task_changes=overrides)
    if task != policy.spec.task:
        raise ValueError(f"{path} was trained on task {policy.spec.task!r}; record it with --task {policy.spec.task}")
    return env, lambda observation: policy.act(_batched(observation))[0], None


def _gpt(task: str, path: Path, overrides: dict[str, Any], prompt: str | None) -> Rollout:
    from distill.experts.loading import load_expert
    from distill.gpt.completion import CompletionController, ExpertPrompt
    from distill.gpt.model import load_gpt

    _require_task(task, ("motion_completion",), "the GPT")
    if prompt is None:
        raise ValueError("the GPT needs a prompt: pass --prompt EXPERT_DIR (the expert of the snippet to complete)")
    gpt = load_gpt(path)
    expert = ExpertPrompt(load_expert(prompt))
    keys = tuple(dict.fromkeys([*gpt.spec.observation_sizes, *expert.keys]))
    settings = {"snippets": (str(expert.expert.spec.snippet),), "observables": keys, "ref_steps": expert.ref_steps}
    settings.update(_recorded_clips(prompt))
    env = tasks.make(task, **{**settings, **overrides})  # the prompt's reference steps, as `gpt complete` uses
    controller = CompletionController(gpt, expert, [env.unwrapped], context="cache")  # type: ignore[list-item]
    return env, lambda observation: controller.act([0], _batched(observation))[0], lambda: controller.new_episode(0)


def record(
    task: str,
    policy: str,
    out: str | os.PathLike,
    episodes: int = 1,
    seed: int = 0,
    overrides: dict[str, Any] | None = None,
    prompt: str | None = None,
    video: str | os.PathLike | None = None,
) -> dict[str, Any]:
    """Records ``episodes`` of ``policy`` on ``task`` into the ``.rrd`` file ``out`` (and an mp4 when asked).

    Holds the lock of ``out`` meanwhile (:func:`foundation.run_lock.file_lock`).

    Raises:
        RunFolderInUseError: Another run records into the same file.
    """
    from foundation.run_lock import file_lock
    from tasks.viz.recording import record_rollout

    if Path(out).suffix != ".rrd":
        raise ValueError(f"the recording file must end in .rrd, got {out}")
    with file_lock(out):  # one writer per recording
        env, act, new_episode = build_rollout(task, policy, overrides, prompt, seed)
        if video is not None:
            from tasks.viz.video import VideoRecorder

            env = VideoRecorder(env, video)
        result = record_rollout(env, act, out, episodes=episodes, seed=seed, on_reset=new_episode)
    if video is not None:
        result["video"] = str(video)
    return result


def view(path: str | os.PathLike) -> str:
    """Opens the rerun viewer on ``path`` when one can run here; otherwise says how to open it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"recording {path} does not exist (`mocap-hierarchy record` writes one)")
    viewer = shutil.which("rerun")
    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or os.name == "nt"
    if viewer and has_display:
        subprocess.Popen([viewer, str(path)])
        return f"opened {path} in the rerun viewer"
    return (
        f"no display here to open the viewer. Copy {path} to a machine with a screen and run `rerun {path.name}` "
        "(pip install rerun-sdk==0.41.0), or drag it onto https://app.rerun.io (version 0.41)"
    )
