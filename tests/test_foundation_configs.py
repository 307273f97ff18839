"""Schedules, the PPO block, config files and nested config flags (foundation: schedule, ppo, config_files)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import tomllib
from dataclasses import dataclass, field

import pytest

from foundation.config_cli import (
    add_dataclass_arguments,
    dataclass_flags,
    dataclass_from_args,
    given_fields,
    parse_field_setting,
)
from foundation.config_files import (
    ConfigFileError,
    config_from_dict,
    config_to_dict,
    config_to_toml,
    read_config_file,
    with_settings,
)
from foundation.ppo import PpoConfig
from foundation.schedule import Schedule, ScheduleError


def test_a_piecewise_schedule_holds_each_value_from_its_step():
    schedule = Schedule.parse("3e-4@0,1e-4@600k,3e-5@2M")
    assert [schedule.at(s) for s in (0, 599_999, 600_000, 1_999_999, 2_000_000, 10**9)] == [
        3e-4,
        3e-4,
        1e-4,
        1e-4,
        3e-5,
        3e-5,
    ]
    assert schedule.change_steps() == (600_000, 2_000_000) and schedule.changes and schedule.start == 3e-4


def test_a_linear_schedule_moves_between_its_points_and_keeps_the_last():
    schedule = Schedule.parse("linear:1e-3@0,0@1M")
    assert schedule.at(0) == 1e-3 and schedule.at(250_000) == pytest.approx(7.5e-4)
    assert schedule.at(1_000_000) == 0 and schedule.at(5_000_000) == 0


@pytest.mark.parametrize(
    "text", ["3e-4", "3e-4@0,1e-4@600k", "linear:0.3@0,0.2@2M", "4096@0,16384@2M", "0.1@0,0.05@1500"]
)
def test_a_schedule_reads_back_from_its_text(text):
    schedule = Schedule.parse(text)
    assert Schedule.parse(str(schedule)) == schedule


def test_a_number_is_a_constant_and_equal_parts_split_the_budget_like_the_paper():
    assert Schedule.of(0.3) == Schedule.parse("0.3") == Schedule.constant(0.3) and not Schedule.of(0.3).changes
    assert str(Schedule.equal_parts((1e-5, 6e-6, 3e-6), 150_000_000)) == "1e-5@0,6e-6@50M,3e-6@100M"
    assert Schedule.equal_parts((1.0, 2.0, 3.0), 1024).change_steps() == (342, 683)  # ceil(1024/3), ceil(2048/3)


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("3e-4@0,1e-4", "each needs its step"),
        ("1e-4@5", "first point must be at step 0"),
        ("fast", "is not a number"),
        ("1@0,2@3q", "is not a count"),
        ("1@0,2@5,3@5", "must increase"),
        ("cubic:1@0,2@5", "interpolation"),
    ],
)
def test_a_malformed_schedule_says_what_is_wrong_and_the_expected_form(text, reason):
    with pytest.raises(ScheduleError, match=reason):
        Schedule.parse(text)


def test_the_ppo_block_checks_its_settings_by_name():
    PpoConfig().validate(8192)
    with pytest.raises(ValueError, match="schedule must be one of"):
        PpoConfig(schedule="piecewise").validate()
    with pytest.raises(ValueError, match="stay positive"):
        PpoConfig(learning_rate=Schedule.parse("3e-4@0,0@5")).validate()
    with pytest.raises(ValueError, match=r"minibatch_size .* cannot exceed"):
        PpoConfig(minibatch_size=1024).validate(512)


@dataclass(frozen=True)
class _Job:
    """A job with a nested block.

    Attributes:
        total_steps: Budget.
        ppo: The PPO block.
        noise: A schedule.
        name: Text.
    """

    total_steps: int = 100
    ppo: PpoConfig = field(default_factory=PpoConfig)
    noise: Schedule = field(default_factory=lambda: Schedule.constant(0.1))
    name: str = "job"


def test_a_config_survives_json_and_toml_with_its_block_and_schedules(tmp_path):
    config = _Job(
        total_steps=3_000_000,
        ppo=PpoConfig(learning_rate=Schedule.parse("1.5e-4@0,5e-5@600k"), target_kl=0.3, hidden_layers=(512, 512)),
        noise=Schedule.parse("0.3@0,0.2@2M"),
    )
    data = config_to_dict(config)
    assert data["ppo"]["learning_rate"] == "1.5e-4@0,5e-5@600k" and data["noise"] == "0.3@0,0.2@2M"
    assert config_from_dict(_Job, json.loads(json.dumps(data))) == config
    text = config_to_toml(config, "a comment\non two lines")
    assert text.startswith("# a comment\n# on two lines\n") and "\n[ppo]\n" in text
    assert config_from_dict(_Job, tomllib.loads(text)) == config
    (tmp_path / "job.toml").write_text(text)
    assert read_config_file(_Job, tmp_path / "job.toml") == config
    optional = dataclasses.replace(config, ppo=dataclasses.replace(config.ppo, target_kl=None))
    assert config_from_dict(_Job, tomllib.loads(config_to_toml(optional))) == optional  # None survives TOML


def test_a_bad_config_file_names_the_setting_and_the_fix(tmp_path):
    with pytest.raises(FileNotFoundError, match="--print-config"):
        read_config_file(_Job, tmp_path / "missing.toml")
    (tmp_path / "typo.toml").write_text("total_step = 5\n")
    with pytest.raises(ConfigFileError, match=r"no setting total_step \(settings: "):
        read_config_file(_Job, tmp_path / "typo.toml")
    (tmp_path / "broken.toml").write_text("total_steps = \n")
    with pytest.raises(ConfigFileError, match="not valid TOML"):
        read_config_file(_Job, tmp_path / "broken.toml")
    (tmp_path / "type.toml").write_text('total_steps = 5\n[ppo]\nepochs = "many"\n')
    with pytest.raises(ConfigFileError, match=r"\[ppo\]: epochs"):
        read_config_file(_Job, tmp_path / "type.toml")


def test_settings_change_by_name_nested_ones_bare_or_with_their_block():
    config = with_settings(_Job(), {"learning_rate": "3e-4@0,1e-4@600k", "ppo.epochs": "3", "noise": 0.2})
    assert config.ppo.learning_rate == Schedule.parse("3e-4@0,1e-4@600k") and config.ppo.epochs == 3
    assert config.noise == Schedule.constant(0.2) and config.total_steps == 100
    with pytest.raises(ConfigFileError, match="no setting 'epoch'"):
        with_settings(_Job(), {"epoch": 3})
    with pytest.raises(ConfigFileError, match=r"no setting 'noise\.epochs'"):
        with_settings(_Job(), {"noise.epochs": 3})


def test_a_nested_block_gets_flat_flags_and_schedules_parse_from_the_command_line():
    parser = argparse.ArgumentParser()
    add_dataclass_arguments(parser, _Job)
    args = parser.parse_args(["--learning-rate", "3e-4@0,1e-4@600k", "--epochs", "3", "--hidden-layers", "64", "64"])
    assert given_fields(_Job, args) == {
        "learning_rate": Schedule.parse("3e-4@0,1e-4@600k"),
        "epochs": 3,
        "hidden_layers": (64, 64),
    }
    config = dataclass_from_args(_Job, args)
    assert config.ppo == PpoConfig(learning_rate=Schedule.parse("3e-4@0,1e-4@600k"), epochs=3, hidden_layers=(64, 64))
    assert dataclass_from_args(_Job, parser.parse_args([])) == _Job()
    with pytest.raises(SystemExit):
        parser.parse_args(["--learning-rate", "3e-4@0,1e-4"])  # argparse reports the schedule's error
    assert parse_field_setting(_Job, "learning_rate=3e-4") == ("learning_rate", Schedule.constant(3e-4))
    assert parse_field_setting(_Job, "target_kl=none") == ("target_kl", None)


@dataclass(frozen=True)
class _Switches:
    """Yes/no settings and an optional one.

    Attributes:
        job: A nested block.
        fast: A yes/no setting on by default.
        masks: Yes/no values.
        limit: Optional.
    """

    job: PpoConfig = field(default_factory=PpoConfig)
    fast: bool = True
    masks: tuple[bool, ...] = (True,)
    limit: float | None = None


def test_the_flags_of_a_config_parse_back_to_it():
    job = with_settings(
        _Job(total_steps=7, noise=Schedule.parse("0.3@0,0.2@2M"), name="a b"),
        {"learning_rate": "3e-4@0,1e-4@600k", "hidden_layers": (64, 32), "target_kl": 0.02},
    )
    flags = dataclass_flags(job)
    assert flags[flags.index("--hidden-layers") + 1 :][:2] == ["64", "32"]
    parser = argparse.ArgumentParser()
    add_dataclass_arguments(parser, _Job)
    assert dataclass_from_args(_Job, parser.parse_args(flags)) == job
    assert dataclass_flags(_Job()) == []
    switches = _Switches(fast=False, masks=(False, True), limit=2.5)
    assert dataclass_flags(switches) == ["--no-fast", "--masks", "False", "True", "--limit", "2.5"]
    parser = argparse.ArgumentParser()
    add_dataclass_arguments(parser, _Switches)
    assert dataclass_from_args(_Switches, parser.parse_args(dataclass_flags(switches))) == switches
