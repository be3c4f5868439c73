"""`nerfkit train --help` is derived from the config's sections: every setting a user can type is in a group."""

from __future__ import annotations

import dataclasses

from nerfkit.cli.help import FIRST, GROUPS
from nerfkit.core.config import Config
from nerfkit.training.flags import FROM_DATA, SECTIONS, setting_names


def test_every_setting_is_in_one_help_group():
    grouped = [n for names in GROUPS.values() for n in names]
    assert len(grouped) == len(set(grouped)), "a setting listed in two groups"
    assert set(setting_names()) - FROM_DATA - set(FIRST) <= set(grouped)
    assert set(grouped) <= set(setting_names()), "a group names a setting that does not exist"


def test_a_section_is_one_field_of_config():
    assert SECTIONS == tuple(f.name for f in dataclasses.fields(Config))
    cfg = Config()
    for name, cls in Config.sections().items():
        assert isinstance(getattr(cfg, name), cls)
    assert Config.from_dict(cfg.to_dict()) == cfg
