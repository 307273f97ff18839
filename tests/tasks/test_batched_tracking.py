"""The batched tracking env (MuJoCo Warp, here on Warp's CPU device) equals the CPU env.

From identical states, one step of both gives the same observations (every
observable), reward and episode ends, within float32 tolerance. The first test
to build an env compiles Warp's kernels (about a minute on two cores; Warp
caches them in ~/.cache/warp for later runs).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco_warp", reason="the gpu extra is not installed")
import torch

from tasks.observables import ALL_PROPRIOCEPTION, REFERENCE_PER_STEP, TRACKING_EXTRAS
from tasks.tracking.batched import BatchedTrackingEnv, SnippetBufferError, WarpUnavailableError
from tasks.tracking.batched import backend as warp_backend
from tasks.tracking.env import ClipTrackingEnv, TrackingConfig

EVERY_OBSERVABLE = (*ALL_PROPRIOCEPTION, *REFERENCE_PER_STEP, *TRACKING_EXTRAS)
SNIPPETS = ("SYN_walk_slow-0-200", "SYN_wave-100-300", "SYN_turn_left-149-331")
RELATIVE_TOLERANCE = 5e-4
"""max |batched - CPU| / max(1, max |CPU value|), per observable: float32 physics over six substeps.

Measured at most 1.6e-4 here and 3.3e-4 in another sample (joints_vel_control: a float32 joint-angle
difference divided by 0.03 s); positions and quaternions agree to about 1e-5 of their scale."""

REWARD_TOLERANCE = 1e-5


def rollout_snapshots(config: TrackingConfig, count: int, seed: int) -> list[dict]:
    """States met by the CPU env under noisy playback, each with the next action and what the CPU step gave."""
    env = ClipTrackingEnv(config)
    rng = np.random.default_rng(seed)
    snapshots: list[dict] = []
    env.reset(seed=seed)
    while len(snapshots) < count:
        action = np.clip(env.reference_actuation() + rng.normal(0.0, 0.2, 56), -1, 1)
        take = env.time_step > 0 and rng.random() < 0.25
        if take:
            data = env.data
            snapshot = {
                "physics": {
                    "qpos": data.qpos.copy(),
                    "qvel": data.qvel.copy(),
                    "act": data.act.copy(),
                    "qacc_warmstart": data.qacc_warmstart.copy(),
                    "subtree_linvel": data.subtree_linvel.copy(),
                },
                "snippet": env.snippets.index(env.reference.snippet),
                "time_step": env.time_step,
                "time_step_at_reset": env._time_step_at_reset,
                "episode_length": env._episode_length,
                "episode_return": env._episode_return,
                "contacts": data.ncon,
                "action": action,
            }
        observation, reward, terminated, truncated, info = env.step(action)
        if take:
            snapshot.update(observation=observation, reward=reward, terminated=terminated, truncated=truncated)
            snapshot["summary"] = info if terminated or truncated else None
            snapshots.append(snapshot)
        if terminated or truncated:
            env.reset()
    return snapshots


def load(env: BatchedTrackingEnv, snapshots: list[dict], worlds: list[int]) -> None:
    env.load_worlds(
        worlds,
        {k: np.stack([s["physics"][k] for s in snapshots]) for k in snapshots[0]["physics"]},
        [s["snippet"] for s in snapshots],
        [s["time_step"] for s in snapshots],
        [s["time_step_at_reset"] for s in snapshots],
        [s["episode_length"] for s in snapshots],
        [s["episode_return"] for s in snapshots],
    )


def assert_close(
    expected: list[dict[str, np.ndarray]], actual: dict[str, torch.Tensor], keys, rows: list[int]
) -> dict[str, float]:
    """Each key's worst error relative to its scale, under the tolerance (expected[i] is world rows[i])."""
    worst = {}
    for key in keys:
        cpu = np.stack([row[key] for row in expected])
        batched = actual[key].double().numpy()[rows]
        assert batched.shape == cpu.shape, key
        worst[key] = float(np.max(np.abs(batched - cpu)) / max(1.0, float(np.max(np.abs(cpu)))))
    assert max(worst.values()) < RELATIVE_TOLERANCE, sorted(worst.items(), key=lambda item: -item[1])[:3]
    return worst


@pytest.fixture(scope="module")
def config(clip_library) -> TrackingConfig:
    return TrackingConfig(snippets=SNIPPETS, clips=str(clip_library), observables=EVERY_OBSERVABLE)


@pytest.fixture(scope="module")
def snapshots(config) -> list[dict]:
    return rollout_snapshots(config, count=32, seed=1)


@pytest.fixture(scope="module")
def env(config, snapshots) -> BatchedTrackingEnv:
    batched = BatchedTrackingEnv(config, num_worlds=len(snapshots), device="cpu", seed=0)
    batched.reset()
    return batched


def test_one_step_from_cpu_states_matches_every_observable_reward_and_end(env, snapshots):
    assert sum(s["contacts"] > 0 for s in snapshots) >= len(snapshots) // 2  # states with feet on the floor
    assert any(s["terminated"] or s["truncated"] for s in snapshots)  # and some episode ends
    load(env, snapshots, list(range(len(snapshots))))
    actions = torch.as_tensor(np.stack([s["action"] for s in snapshots]))
    observation, reward, terminated, truncated, ends = env.step(actions)

    np.testing.assert_array_equal(terminated.numpy(), [s["terminated"] for s in snapshots])
    np.testing.assert_array_equal(truncated.numpy(), [s["truncated"] for s in snapshots])
    np.testing.assert_allclose(reward.numpy(), [s["reward"] for s in snapshots], atol=REWARD_TOLERANCE)
    alive = [i for i, s in enumerate(snapshots) if not (s["terminated"] or s["truncated"])]
    worst = assert_close([snapshots[i]["observation"] for i in alive], observation, EVERY_OBSERVABLE, alive)
    assert len(worst) == len(EVERY_OBSERVABLE) == 36
    for i, snapshot in enumerate(snapshots):  # the finished episodes' scores are MoCapAct's
        if snapshot["summary"] is not None:
            assert bool(ends.done[i])
            for name in ("normalized_episode_length", "normalized_episode_reward", "episode_return"):
                assert float(getattr(ends, name)[i]) == pytest.approx(snapshot["summary"][name], abs=1e-5)
            assert int(ends.episode_length[i]) == snapshot["summary"]["episode_length"]


def test_reset_matches_cpu_reset_including_sensors_without_actuation(env, config):
    cpu = ClipTrackingEnv(config)
    rng = np.random.default_rng(4)
    snippets = rng.integers(0, len(SNIPPETS), env.num_worlds)
    starts = []
    for snippet in snippets:
        reference = cpu.references[snippet]
        starts.append(reference.first_frame + int(rng.integers(cpu.start_counts[snippet])))
    observation = env.reset(snippets=snippets, start_steps=starts)
    expected = [
        cpu.reset(options={"snippet": int(s), "start_step": int(t)})[0] for s, t in zip(snippets, starts, strict=True)
    ]
    assert_close(expected, observation, EVERY_OBSERVABLE, list(range(env.num_worlds)))


def test_an_unstable_world_is_reset_and_counted_without_touching_the_others(env, snapshots):
    chosen = [s for s in snapshots if not (s["terminated"] or s["truncated"])][:1] * env.num_worlds
    load(env, chosen, list(range(env.num_worlds)))
    env.physics.view.qvel[2, 10] = float("nan")
    before = int(env.unstable_resets)
    actions = torch.as_tensor(np.stack([s["action"] for s in chosen]))
    observation, reward, terminated, _, ends = env.step(actions)
    assert int(env.unstable_resets) == before + 1
    assert bool(terminated[2]) and float(reward[2]) == 0.0 and bool(ends.done[2])
    assert int(env.episode_length[2]) == 0  # already reset into a new episode, finite again
    assert all(bool(torch.isfinite(v[2]).all()) for v in observation.values())
    others = [i for i in range(env.num_worlds) if i != 2]
    np.testing.assert_allclose(reward[others].numpy(), chosen[0]["reward"], atol=REWARD_TOLERANCE)
    assert_close([chosen[0]["observation"]] * len(others), observation, EVERY_OBSERVABLE, others)


def test_nan_actions_are_refused_naming_the_worlds(env):
    actions = torch.zeros(env.num_worlds, 56)
    actions[3, 7] = float("nan")
    with pytest.raises(ValueError, match=r"worlds \[3\] contain NaN"):
        env.step(actions)
    with pytest.raises(ValueError, match="actions must have shape"):
        env.step(torch.zeros(env.num_worlds, 55))


def test_pinned_snippets_mix_in_one_batch_and_episodes_restart_there(config):
    pinned = [0, 2, 1, 2]
    batched = BatchedTrackingEnv(config, num_worlds=4, device="cpu", world_snippets=pinned, seed=3)
    batched.reset()
    assert batched.snippet.tolist() == pinned
    last = batched.bank.last_step[batched.snippet]
    batched.time_step = last - 1  # one step before each snippet's end
    _, _, terminated, truncated, ends = batched.step(batched.bank.playback[batched.snippet, batched.time_step] * 0)
    assert bool((terminated | truncated).all()) and bool(ends.done.all())
    assert batched.snippet.tolist() == pinned  # restarted on the same snippets
    assert bool((batched.time_step < last).all()) and int(batched.episode_length.sum()) == 0
    with pytest.raises(ValueError, match="one snippet index per world"):
        BatchedTrackingEnv(config, num_worlds=3, device="cpu", world_snippets=[0, 1])


def test_snippets_longer_than_the_buffers_and_unknown_snippets_are_refused(config, clip_library):
    with pytest.raises(SnippetBufferError, match="raise max_frames to at least 201"):
        BatchedTrackingEnv(config, num_worlds=2, device="cpu", max_frames=150)
    with pytest.raises(ValueError, match="SYN_no_such_motion"):
        BatchedTrackingEnv(TrackingConfig(snippets=("SYN_no_such_motion",), clips=str(clip_library)), 2, "cpu")


def test_cuda_without_a_gpu_and_a_missing_extra_say_what_to_do(monkeypatch):
    import warp

    if warp.get_cuda_devices():
        pytest.skip("this machine has a GPU")
    with pytest.raises(WarpUnavailableError, match="--device cpu"):
        warp_backend.resolve_device("cuda")
    assert warp_backend.resolve_device("auto") == ("cpu", "cpu")

    def missing(name):
        raise ImportError(f"No module named {name!r}", name=name)

    monkeypatch.setattr(warp_backend.importlib, "import_module", missing)
    with pytest.raises(WarpUnavailableError, match=r"\.\[gpu\]"):
        warp_backend.require_warp()


def test_residual_actions_add_the_cpu_envs_playback_targets(env, config):
    cpu = ClipTrackingEnv(config)
    for index, reference in enumerate(cpu.references):
        for frame in (0, 7, reference.num_frames - 2, reference.num_frames - 1):  # the last frame holds itself
            cpu._reference, cpu._time_step = reference, frame
            np.testing.assert_allclose(env.bank.playback[index, frame].numpy(), cpu.reference_actuation(), atol=1e-6)
