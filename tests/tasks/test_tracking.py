import h5py
import numpy as np
import pytest

from tasks.clips.format import ClipFileError
from tasks.observables import OBSERVABLE_SETS
from tasks.tracking.env import ClipMismatchError, ClipTrackingEnv, TrackingConfig, reference_action


@pytest.fixture(scope="module")
def env(clip_library, walker):
    return ClipTrackingEnv(TrackingConfig(snippets=("SYN_walk_slow-0-182",), clips=str(clip_library)), walker=walker)


def test_bad_actions_are_refused_with_a_reason(env):
    env.reset(seed=0)
    action = np.zeros(56)
    action[3] = np.nan
    with pytest.raises(ValueError, match=r"NaN or inf at indices \[3\]"):
        env.step(action)
    with pytest.raises(ValueError, match=r"action\[7\] = 1.5000 is outside \[-1, 1\]"):
        env.step(np.where(np.arange(56) == 7, 1.5, 0.0))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(55))


def test_step_needs_a_live_episode(clip_library, walker):
    fresh = ClipTrackingEnv(TrackingConfig(snippets=("SYN_stand",), clips=str(clip_library)), walker=walker)
    with pytest.raises(RuntimeError, match="reset"):
        fresh.step(np.zeros(56))


def test_a_snippet_too_short_for_random_starts_starts_at_its_first_frame(clip_library, walker):
    config = TrackingConfig(snippets=("SYN_stand-0-12",), clips=str(clip_library))
    with pytest.warns(UserWarning, match="too short for random starts"):
        env = ClipTrackingEnv(config, walker=walker)
    starts = {env.reset(seed=seed)[1]["start_step"] for seed in range(5)}
    assert starts == {0}


@pytest.mark.parametrize(
    ("config", "error", "message"),
    [
        (dict(snippets=("SYN_nope",)), ClipFileError, "SYN_nope is not in the file"),
        (dict(snippets=("SYN_stand-5",)), ValueError, "bad snippet id"),
        (dict(init="middle"), ValueError, "init must be"),
        (dict(observables="everything"), ValueError, "unknown observable set"),
        (dict(observables=("walker/joints_pos", "walker/nope")), ValueError, "unknown observables"),
        (dict(snippets=()), ValueError, "at least one snippet"),
    ],
)
def test_bad_configs_are_explained(clip_library, walker, config, error, message):
    with pytest.raises(error, match=message):
        ClipTrackingEnv(TrackingConfig(**{"clips": str(clip_library), **config}), walker=walker)


@pytest.mark.parametrize(
    ("name", "size"),
    [
        ("decoder", 56 + 56 + 3 + 3 + 12 + 3 + 56 + 10 + 6),
        ("expert", 206),
        ("gpt", 206),
        ("encoder", 205 + 1 + 5 * 93 + 5 * 124),
    ],
)
def test_observable_sets(clip_library, walker, name, size):
    env = ClipTrackingEnv(
        TrackingConfig(snippets=("SYN_stand",), clips=str(clip_library), observables=name), walker=walker
    )
    observation, _ = env.reset(seed=1)
    assert tuple(observation) == OBSERVABLE_SETS[name]
    assert sum(v.size for v in observation.values()) == size
    assert observation in env.observation_space


def test_full_set_matches_dm_control_size(env):
    observation, _ = env.reset(seed=0)
    # dm_control has 28 keys, 3 of them empty (props, force sensors): 25 non-empty, 2848 values
    assert len(observation) == 25 and sum(v.size for v in observation.values()) == 2848


def test_random_starts_avoid_the_last_frames(env):
    starts = {env.reset(seed=s)[1]["start_step"] for s in range(300)}
    # snippet 0-182 ends at step 182: starts < 182 - max(ref_steps) - min_steps = 168
    assert min(starts) == 0 and max(starts) == 167


def test_start_init_always_starts_at_the_snippet_start(clip_library, walker):
    env = ClipTrackingEnv(
        TrackingConfig(snippets=("SYN_walk_slow-149-331",), clips=str(clip_library), init="start"), walker=walker
    )
    assert {env.reset(seed=s)[1]["start_step"] for s in range(10)} == {149}


def test_reaching_the_end_truncates_with_full_normalised_length(env):
    env.reset(options={"start_step": 170})
    truncated = terminated = False
    info = {}
    while not (truncated or terminated):
        _, _, terminated, truncated, info = env.step(reference_action(env))
    assert truncated and not terminated
    assert info["normalized_episode_length"] == pytest.approx(1.0)
    assert 0.0 < info["normalized_episode_reward"] <= 1.0
    # frames 0..182 (dm_control includes the end step); episodes stop 5 + 1 frames early
    assert info["episode_length"] == 183 - 5 - 1 - 170


def test_falling_terminates_with_partial_normalised_length(env):
    env.reset(options={"start_step": 0})
    terminated = truncated = False
    info = {}
    while not (terminated or truncated):
        _, _, terminated, truncated, info = env.step(-np.ones(56))
    assert terminated and info["termination_error"] > 0.3
    assert 0.0 < info["normalized_episode_length"] < 0.5
    assert info["normalized_episode_length"] == pytest.approx(info["episode_length"] / (183 - 5 - 1))


def test_reward_terms_sum_to_the_reward(env):
    env.reset(seed=2)
    _, reward, _, _, info = env.step(reference_action(env))
    assert sum(info["reward_terms"].values()) == pytest.approx(reward)
    assert set(info["reward_terms"]) == {
        "termination",
        "center_of_mass",
        "joints_velocity",
        "appendages",
        "body_quaternions",
    }


def test_residual_actions_offset_the_reference_pose(clip_library, walker):
    def first_steps(residual, action):
        env = ClipTrackingEnv(
            TrackingConfig(snippets=("SYN_wave",), clips=str(clip_library), init="start", residual_actions=residual),
            walker=walker,
        )
        env.reset(seed=0)
        expected = env.reference_actuation()
        observation, _, _, _, info = env.step(action)
        return observation["walker/joints_pos"], info["action"], expected

    # a zero residual is the playback controller
    residual_obs, applied, expected = first_steps(True, np.zeros(56))
    np.testing.assert_allclose(applied, expected)
    absolute_obs, _, _ = first_steps(False, expected)
    np.testing.assert_array_equal(residual_obs, absolute_obs)
    # offsets add to the reference actuation and the sum is clipped to [-1, 1]
    _, applied, expected = first_steps(True, np.full(56, 0.5))
    np.testing.assert_allclose(applied, np.clip(expected + 0.5, -1, 1))


def test_action_noise_is_seeded(clip_library, walker):
    def rollout(noise, seed):
        env = ClipTrackingEnv(
            TrackingConfig(snippets=("SYN_stand",), clips=str(clip_library), action_noise=noise, init="start"),
            walker=walker,
        )
        env.reset(seed=seed)
        for _ in range(5):
            observation, *_ = env.step(reference_action(env))
        return observation["walker/joints_pos"]

    assert np.array_equal(rollout(0.1, 1), rollout(0.1, 1))
    assert not np.array_equal(rollout(0.1, 1), rollout(0.1, 2))
    assert not np.array_equal(rollout(0.1, 1), rollout(0.0, 1))


def test_clip_for_another_walker_is_detected(clip_library, walker, tmp_path):
    broken = tmp_path / "broken.h5"
    broken.write_bytes(clip_library.read_bytes())
    with h5py.File(broken, "r+") as f:
        f["SYN_stand/walkers/walker_0/body_positions"][...] *= 0.8  # a smaller walker's bodies
    env = ClipTrackingEnv(TrackingConfig(snippets=("SYN_stand",), clips=str(broken)), walker=walker)
    with pytest.raises(ClipMismatchError, match="does not reproduce"):
        env.reset(seed=0)


def test_reset_options_are_validated(env):
    with pytest.raises(ValueError, match="outside snippet"):
        env.reset(options={"start_step": 500})
    with pytest.raises(ValueError, match="not tracked"):
        env.reset(options={"snippet": "SYN_wave"})
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"frame": 3})
