"""A five-minute tour: every registered task, and tracking one snippet.

Run: python examples/tour_of_the_tasks.py
"""

import numpy as np

import tasks
from tasks.tracking.env import reference_action

# 1. Every task is one call away; overrides are fields of the task's config.
for name in tasks.task_names():
    env = tasks.make(name)
    observation, _ = env.reset(seed=0)
    size = sum(value.size for value in observation.values())
    print(f"{name:<18} {len(observation):>2} observables, {size:>4} values, action {env.action_space.shape}")

# 2. Track a snippet with the open-loop playback controller (no learning):
#    the walker follows the reference for a while, then drifts and falls.
env = tasks.make("tracking", snippets=("SYN_walk_slow-0-182",), init="start", observables="decoder")
observation, info = env.reset(seed=0)
print(f"\ntracking {info['snippet']} from frame {info['start_step']}")
total = 0.0
while True:
    observation, reward, terminated, truncated, info = env.step(reference_action(env))
    total += reward
    if terminated or truncated:
        break
print(
    f"episode: {info['episode_length']} steps, return {total:.1f}, "
    f"normalised reward {info['normalized_episode_reward']:.3f}, length {info['normalized_episode_length']:.3f}"
)

# 3. Downstream tasks score velocities with a pure function you can reuse.
from tasks.downstream.velocity_control import reward  # noqa: E402

print(
    f"\nvelocity reward, 1 m/s east vs. commanded 1.2 m/s north-east: "
    f"{reward(np.array([1.0, 0.0]), 1.2 * np.array([np.sqrt(0.5), np.sqrt(0.5)])):.3f}"
)
