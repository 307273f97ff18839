"""Our tracking environment equals dm_control's MultiClipMocapTracking."""

import numpy as np
import pytest

from tasks.tracking.env import ClipTrackingEnv, TrackingConfig, reference_action
from tasks.tracking.stock import make_stock_tracking, stock_start

SNIPPETS = ("SYN_walk_slow-0-200", "SYN_squat", "SYN_wave-100-300", "SYN_turn_left-149-331")


@pytest.mark.parametrize(
    ("init", "seed", "observables", "keys"),
    [("random", 3, "full", 25), ("start", 5, "full", 25), ("random", 7, "rollout", 35)],
)
def test_observations_rewards_and_ends_match_dm_control(clip_library, init, seed, observables, keys):
    config = TrackingConfig(snippets=SNIPPETS, clips=str(clip_library), init=init, observables=observables)
    ours = ClipTrackingEnv(config)
    stock = make_stock_tracking(config, clip_library, seed=seed, all_proprioception=observables == "rollout")
    rng = np.random.default_rng(seed)
    worst: dict[str, float] = {}
    steps = resets = 0

    def compare(stock_observation, observation):
        assert set(observation) <= set(stock_observation)
        for key, value in observation.items():
            expected = np.asarray(stock_observation[key]).ravel()
            assert value.shape == expected.shape, key
            worst[key] = max(worst.get(key, 0.0), float(np.max(np.abs(expected - value), initial=0.0)))

    while steps < 320 or resets < 4:
        timestep = stock.reset()
        snippet, start = stock_start(stock)
        observation, _ = ours.reset(options={"snippet": snippet, "start_step": start})
        resets += 1
        compare(timestep.observation, observation)
        done = False
        while not done:
            action = np.clip(reference_action(ours) + 0.1 * rng.standard_normal(56), -1, 1)
            timestep = stock.step(action)
            observation, reward, terminated, truncated, _ = ours.step(action)
            steps += 1
            compare(timestep.observation, observation)
            assert reward == pytest.approx(timestep.reward, abs=1e-6)
            done = terminated or truncated
            assert done == timestep.last()
            if done:
                assert terminated == (timestep.discount == 0.0)
    assert len(worst) == keys  # every non-empty float observable of dm_control's task
    assert max(worst.values()) < 1e-6, sorted(worst.items(), key=lambda item: -item[1])[:3]
