import subprocess
import sys

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


def test_gymnasium_ids_work_in_a_fresh_interpreter_with_no_task_made_first(clip_library):
    """The guide's use: Gymnasium imported, then ``tasks``, then ``gymnasium.make(id)``; ``import tasks`` alone
    loads no Gymnasium, and after it :func:`tasks.register_with_gymnasium` makes the ids."""
    code = (
        "import gymnasium\n"
        "import tasks\n"
        "print(sorted(i for i in gymnasium.registry if i.startswith('MocapHierarchy/')))\n"
        "env = gymnasium.make('MocapHierarchy/VelocityControl-v0', max_steps=3)\n"
        "print(type(env.unwrapped).__name__, env.unwrapped.config.max_steps)\n"
    )
    lines = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    assert lines[0] == str(sorted(entry.gym_id for entry in REGISTRY.values()))
    assert lines[1] == "VelocityControlEnv 3"  # keyword arguments of gymnasium.make reach the config
    code = (
        "import sys\n"
        "import tasks\n"
        "print('gymnasium' in sys.modules)\n"
        "tasks.register_with_gymnasium()\n"
        "import gymnasium\n"
        "print(gymnasium.spec('MocapHierarchy/GoToTarget-v0').kwargs)\n"
    )
    lines = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    assert lines == ["False", "{'name': 'go_to_target'}"]


def test_overrides_reach_the_config(clip_library):
    env = tasks.make("velocity_control", max_speed=1.0, max_steps=5)
    assert env.unwrapped.config.max_speed == 1.0


def test_unknown_names_list_the_valid_ones():
    with pytest.raises(ValueError, match="registered tasks: tracking, tracking_expert, go_to_target, velocity_control"):
        tasks.make("walk_on_moon")
    with pytest.raises(TypeError, match=r"no setting\(s\) \['speed'\]; valid settings: .*max_speed"):
        tasks.make("velocity_control", speed=2.0)


# Tasks that plug in -----------------------------------------------------------

USER_TASK = '''
from dataclasses import dataclass

import numpy as np

import tasks
from tasks.downstream.walker_task import WalkerTaskEnv


@dataclass(frozen=True)
class StandStillConfig:
    max_steps: int = 40


class StandStill(WalkerTaskEnv):
    """One point per step on its feet."""

    def __init__(self, config: StandStillConfig) -> None:
        super().__init__({"clock": 1}, config.max_steps)

    def _task_reset(self):
        return np.zeros(2), 0.0

    def _task_step(self):
        return 1.0, False, {}

    def _task_observation(self):
        return {"clock": np.array([self.steps / 40.0])}


def register_all():
    tasks.register("{name}", StandStillConfig, StandStill, "stand still (a test task)")


register_all()
'''


@pytest.fixture
def user_task(tmp_path, monkeypatch):
    """A task registered from a user's module; removed from the registries afterwards."""
    name = "stand_still_test"
    module = tmp_path / "my_tasks_for_test.py"
    module.write_text(USER_TASK.replace("{name}", name))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield name, module
    tasks.REGISTRY.pop(name, None)
    gym.registry.pop(f"MocapHierarchy/{name.title().replace('_', '')}-v0", None)


def test_builtin_tracking_task_tracks_the_whole_synthetic_library():
    from tasks.clips.synthetic.library import SYNTHETIC_CLIPS

    config = REGISTRY["tracking"].config()
    assert config.snippets == tuple(recipe.clip_id for recipe in SYNTHETIC_CLIPS)
    assert REGISTRY["tracking"].config(snippets=("SYN_wave",)).snippets == ("SYN_wave",)  # an override wins


def test_a_registered_user_task_is_a_task_like_the_builtin_ones(clip_library, user_task, capsys):
    import importlib

    from mocap_hierarchy.cli import main

    name, _ = user_task
    importlib.import_module("my_tasks_for_test")
    assert name in tasks.task_names()
    env = tasks.make(name, max_steps=3)
    env.reset(seed=0)
    steps = 0
    while True:
        steps += 1
        _, reward, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape))
        if terminated or truncated:
            break
    assert steps == 3 and reward == 1.0  # the override reached the config
    assert gym.make("MocapHierarchy/StandStillTest-v0").unwrapped.observation_space["clock"].shape == (1,)
    assert main(["tasks"]) == 0
    assert f"{name:<18}MocapHierarchy/StandStillTest-v0" in capsys.readouterr().out


def test_registering_checks_names_configs_and_clashes(user_task):
    import importlib

    name, _ = user_task
    module = importlib.import_module("my_tasks_for_test")
    module.register_all()  # the same registration again: a no-op
    with pytest.raises(ValueError, match="is taken"):
        tasks.register(name, module.StandStillConfig, lambda config: None)
    with pytest.raises(ValueError, match="lower case"):
        tasks.register("Stand Still", module.StandStillConfig, module.StandStill)
    with pytest.raises(TypeError, match="must be a dataclass"):
        tasks.register("stand_still_other", dict, module.StandStill)


def test_an_installed_package_adds_tasks_through_the_entry_point_group(user_task, monkeypatch):
    from importlib import metadata

    from tasks import registry

    name, _ = user_task
    plugin = metadata.EntryPoint(name="mine", value="my_tasks_for_test:register_all", group=registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(metadata, "entry_points", lambda group: [plugin] if group == plugin.group else [])
    monkeypatch.setattr(registry, "_plugins_loaded", False)
    assert name not in REGISTRY
    assert registry.entry(name).description == "stand still (a test task)"  # loaded on first look-up


def test_tasks_from_a_file_reach_spawned_transfer_workers_eval_and_record(clip_library, user_task, tmp_path, capsys):
    from mocap_hierarchy.cli import main

    name, module = user_task
    out = tmp_path / "run"
    common = ["--tasks-from", str(module)]
    ppo = "--n-envs 2 --steps-per-update 64 --minibatch-size 32 --epochs 1 --hidden-layers 16 --device cpu"
    train = [*common, "transfer", "train", "--task", name, "--out", str(out), "--steps", "64", *ppo.split()]
    assert main([*train, "--subprocess-envs"]) == 0  # workers start with spawn: the task travels by value
    assert main([*common, "transfer", "eval", str(out), "--episodes", "1", "--max-steps", "5"]) == 0
    assert f"{name}: return 5.00" in capsys.readouterr().out
    recording = tmp_path / "stand.rrd"
    args = [*common, "record", "--task", name, "--policy", str(out / "policy.safetensors"), "--out", str(recording)]
    assert main([*args, "--set", "max_steps=4"]) == 0
    assert recording.is_file()


def test_an_unknown_setting_is_bad_input_for_the_command_line(tmp_path, capsys):
    from mocap_hierarchy.cli import main

    out = str(tmp_path / "x.rrd")
    assert main(["record", "--task", "tracking", "--policy", "random", "--out", out, "--set", "max_steps=3"]) == 2
    assert "task 'tracking' has no setting(s) ['max_steps']" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_one_name_set_where_a_tuple_of_names_is_taken_is_a_tuple_of_that_name():
    config = REGISTRY["tracking"].config(snippets="CMU_016_22-0-82", clips="cmu-locomotion-v1")
    assert config.snippets == ("CMU_016_22-0-82",) and config.clips == "cmu-locomotion-v1"  # a str field stays one
    assert REGISTRY["tracking"].config(snippets=("A-0-9", "B-0-9")).snippets == ("A-0-9", "B-0-9")
