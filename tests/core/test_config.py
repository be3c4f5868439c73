"""Config: every preset validates and round-trips through JSON; a bad value or type is one ConfigError
naming the flag; settings that earlier versions wrote and no model reads are dropped on load."""

import json

import pytest

from nerfkit.core.config import RETIRED, Config
from nerfkit.core.errors import ConfigError
from nerfkit.core.presets import PRESETS, preset


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_round_trip(name):
    cfg = preset(name)
    assert Config.from_dict(json.loads(cfg.to_json())) == cfg


def test_a_wrong_type_names_the_flag():
    d = preset("ngp").to_dict()
    d["train"]["max_steps"] = "many"
    with pytest.raises(ConfigError, match=r"train.max_steps must be int .*set --max-steps"):
        Config.from_dict(d)


@pytest.mark.parametrize("section, name, value, says", [
    ("train", "precrop_frac", 1.5, r"--precrop-frac must be in \(0, 1\]"),
    ("field", "hidden", 0, r"--hidden must be >= 1 \(got 0\)"),
    ("field", "bound", float("nan"), r"--bound must be a finite number \(got nan\)"),
    ("sampler", "occ_warmup", -1, r"--occ-warmup must be >= 0 \(got -1\)"),
    ("sampler", "occ_warmup_decay", 1.5, r"--occ-warmup-decay must be in \(0, 1\) \(got 1.5\)"),
    ("train", "adam_eps", -1.0, r"--adam-eps must be positive"),
])
def test_a_value_out_of_range_is_refused(section, name, value, says):
    d = preset("ngp").to_dict()
    d[section][name] = value
    with pytest.raises(ConfigError, match=says):
        Config.from_dict(d)


def test_not_a_config_and_retired_settings():
    with pytest.raises(ConfigError, match="not a nerfkit config"):
        Config.from_dict({"data": {}})
    d = preset("ngp").to_dict()
    for name in RETIRED:
        section, key = name.split(".")
        d[section][key] = 1
    assert Config.from_dict(d) == preset("ngp")


def test_unknown_preset():
    with pytest.raises(ConfigError, match="unknown preset 'nope'; choose one of"):
        preset("nope")


def test_a_splat_run_from_before_pixel_loss_keeps_its_l1():
    """The default pixel loss became rmse; a run folder written before the setting existed trained with L1,
    so loading (and resuming) it keeps L1, while a config that names the setting keeps what it names."""
    d = preset("splat").to_dict()
    assert d["splat"].pop("pixel_loss") == "rmse"
    assert Config.from_dict(d).splat.pixel_loss == "l1"
    d["splat"]["pixel_loss"] = "rmse"
    assert Config.from_dict(d).splat.pixel_loss == "rmse"
    assert Config.from_dict(preset("ngp").to_dict() | {"splat": {}}).splat == preset("ngp").splat
