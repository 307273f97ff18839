import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import tasks
from tasks.registry import REGISTRY


@pytest.mark.parametrize("name", tasks.task_names())
def test_every_registered_task_passes_gymnasium_checks_and_runs(clip_library, name):
    env = tasks.make(name)
    check_env(env, skip_render_check=True)
    observation, _ = env.reset(seed=0)
    episodes = 0
    for _ in range(300):
        observation, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert observation in env.observation_space
        assert np.isfinite(reward)
        if terminated or truncated:
            episodes += 1
            env.reset()
    assert episodes >= 1  # random actions make the walker fall


@pytest.mark.parametrize("name", tasks.task_names())
def test_gymnasium_ids(clip_library, name):
    env = gym.make(REGISTRY[name].gym_id)
    observation, _ = env.reset(seed=1)
    assert observation in env.observation_space
    env.close()


def test_overrides_reach_the_config(clip_library):
    env = tasks.make("velocity_control", max_speed=1.0, max_steps=5)
    assert env.unwrapped.config.max_speed == 1.0


def test_unknown_names_list_the_valid_ones():
    with pytest.raises(ValueError, match="registered tasks: tracking, tracking_expert, go_to_target, velocity_control"):
        tasks.make("walk_on_moon")
    with pytest.raises(TypeError, match=r"no setting\(s\) \['speed'\]; valid settings: .*max_speed"):
        tasks.make("velocity_control", speed=2.0)
