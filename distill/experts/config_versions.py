"""Expert settings as run folders store them (``config.json``, ``done.json``), from any version, in one place.

Version 2 (written since the PPO block and schedules): :func:`foundation.config_files.config_to_dict`
of :class:`~distill.experts.config.ExpertConfig`, with ``"version": 2``. Version 1 (no ``version``
key): the flat form, where every schedule was a value plus parallel tuples of switch steps and later
values, and the PPO settings sat beside the rest. :func:`read_expert_settings` turns either into the
current config, so a run folder written before still resumes and its experts still load; settings
that no longer exist are refused with the way out.
"""

from __future__ import annotations

from typing import Any

from distill.experts.config import ExpertConfig
from foundation.config_files import config_from_dict, config_to_dict
from foundation.schedule import Schedule

SETTINGS_VERSION = 2

_PPO_FIELDS = ("epochs", "minibatch_size", "clip_range", "gae_lambda", "gamma", "max_grad_norm", "desired_kl")
_REMOVED = ("termination_start", "termination_curriculum_steps", "snapshot_steps", "branch_step")


class RemovedSettingError(ValueError):
    """A run folder was written with a setting this version no longer has."""


def expert_settings_json(config: ExpertConfig) -> dict[str, Any]:
    """What a run folder stores of ``config`` (the current version)."""
    return {"version": SETTINGS_VERSION, **config_to_dict(config)}


def read_expert_settings(values: dict[str, Any], where: str = "expert settings") -> ExpertConfig:
    """The config a run folder stored, of any version.

    Raises:
        RemovedSettingError: The run used a setting that was removed (the message says what to do).
        foundation.config_files.ConfigFileError: An unknown setting or a value of the wrong type.
    """
    values = dict(values)
    version = values.pop("version", 1)
    if version == 1:
        values = _from_version_1(values, where)
    elif version != SETTINGS_VERSION:
        raise ValueError(f"{where}: settings version {version} is newer than this library's ({SETTINGS_VERSION})")
    return config_from_dict(ExpertConfig, values, where)


def _from_version_1(flat: dict[str, Any], where: str) -> dict[str, Any]:
    """Version 1's flat settings in version 2's form."""
    if flat.get("termination_curriculum_steps") or flat.get("branch_step"):
        raise RemovedSettingError(
            f"{where} uses the termination curriculum or a snapshot branch, which were removed (the curriculum "
            "measured worse; a run starts from another with start_from); finish it with the library at commit 0e51b82 "
            "before this change, or start it again"
        )
    for name in _REMOVED:
        flat.pop(name, None)
    total = int(flat.get("total_steps", ExpertConfig.total_steps))
    ppo = {name: flat.pop(name) for name in _PPO_FIELDS if name in flat}
    if "hidden_layers" in flat:
        ppo["hidden_layers"] = flat.pop("hidden_layers")
    rule = flat.pop("schedule", "piecewise")
    rates = [float(r) for r in flat.pop("learning_rates", [1e-5, 6e-6, 3e-6])]
    rate_steps = [int(s) for s in flat.pop("learning_rate_steps", [])]
    if rule == "adaptive":
        ppo.update(schedule="adaptive", learning_rate=str(Schedule.constant(rates[0])))
    else:
        if rate_steps:
            ppo.update(schedule="fixed", learning_rate=_schedule_text(rates, rate_steps))
        else:  # the rates shared the budget in equal parts
            ppo.update(schedule="fixed", learning_rate=str(Schedule.equal_parts(tuple(rates), total)))
    flat["ppo"] = ppo
    for name, steps_key, later_key in (
        ("steps_per_update", "steps_per_update_steps", "later_steps_per_update"),
        ("action_std", "action_std_steps", "later_action_stds"),
        ("eval_episodes", "eval_episodes_steps", "later_eval_episodes"),
    ):
        steps, later = flat.pop(steps_key, []), flat.pop(later_key, [])
        if name in flat:
            flat[name] = _schedule_text([flat[name], *later], steps)
    if "branch_from" in flat:
        flat["start_from"] = flat.pop("branch_from")
    return flat


def _schedule_text(values: list[float], switch_steps: list[int]) -> str:
    """The schedule holding ``values[0]`` from step 0 and ``values[i + 1]`` from ``switch_steps[i]`` on."""
    return str(Schedule(tuple(zip((0, *switch_steps), values, strict=True))))
