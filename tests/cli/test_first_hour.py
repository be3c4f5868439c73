"""The README's "Your own photos", as a newcomer follows it: its first command as written (on photos of the
procedural scene), then each `next:` command the previous one printed, literally. The only change: the
default preset is made small (its budget of 10 minutes cut to seconds, its hash grid, march and proposal
samples shrunk: the photos make an unbounded scene, so the 60-frame orbit renders with proposal sampling, and
at the preset's 64 + 32 + 32 samples per ray it took most of this test's time), so the walk fits the suite."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import imageio.v3 as iio
import photos
import pytest

from nerfkit.cli.main import main
from nerfkit.core import presets

README = Path(__file__).resolve().parents[2] / "README.md"
SECONDS = 15  # the default training budget for this walk (10 minutes in real use; compiling counts in it)


def _readme_commands() -> list[str]:
    text = README.read_text()
    block = text[text.index("## Your own photos"):]
    code = block[block.index("```bash") + 7:block.index("```", block.index("```bash") + 7)]
    return [line.split("#")[0].strip() for line in code.strip().splitlines()]


def _run(cmd: str, capsys) -> tuple[int, str, list[str]]:
    argv = shlex.split(cmd)
    assert argv[0] == "nerfkit", cmd
    capsys.readouterr()
    code = main(argv[1:])
    out = capsys.readouterr()
    hints = re.findall(r"^next: (.+)$", out.out, re.M)
    return code, out.out + out.err, hints


def test_your_own_photos_following_the_printed_hints(tmp_path, monkeypatch, capsys):
    commands = _readme_commands()
    assert len(commands) == 3 and commands[0].startswith("nerfkit process-data images PHOTOS/ --out data/thing")
    shots = tmp_path / "PHOTOS"
    shots.mkdir()
    for k, rgb in enumerate(photos.arc_photos(8, 128)):
        iio.imwrite(shots / f"IMG_{k:04d}.png", rgb)
    monkeypatch.chdir(tmp_path)
    fast = presets.PRESETS["ngp"]

    def ngp_with_a_short_default():
        cfg = fast()
        cfg.train.max_minutes = SECONDS / 60
        cfg.field.hash_levels, cfg.field.hash_log2_size, cfg.field.hash_max_res = 8, 12, 128
        cfg.sampler.occ_res, cfg.sampler.march_steps, cfg.sampler.max_samples = 32, 64, 1 << 14
        cfg.sampler.proposal_samples, cfg.sampler.field_samples = 16, 8
        cfg.train.batch_rays, cfg.train.val_views = 1024, 1
        return cfg

    monkeypatch.setitem(presets.PRESETS, "ngp", ngp_with_a_short_default)

    code, out, hints = _run(commands[0], capsys)  # as the README writes it
    assert code == 0, out
    assert "registered 8 of 8 photos" in out
    assert hints == ["nerfkit train data/thing --out runs/thing"] == [commands[1]]

    code, out, hints = _run(hints[0], capsys)
    assert code == 0, out
    minutes = f"{SECONDS / 60:g}"
    assert f"budget: {minutes} min of wall time" in out and "the ngp default" in out
    assert "compiling the training step" in out
    assert re.search(rf"--max-minutes {minutes} reached at step (\d+)", out)
    assert hints == ["nerfkit render runs/thing --orbit 60"] == [commands[2]]
    report = (tmp_path / "runs" / "thing" / "report.html").read_text()
    assert "hash grid 8 levels" in report and "D=8" not in report  # the model that ran, not the MLP's settings

    code, out, hints = _run(hints[0], capsys)
    assert code == 0, out
    info = json.loads(next((tmp_path / "runs" / "thing" / "renders").glob("orbit60_*/render.json")).read_text())
    assert info["frames"] == 60 and hints == []


@pytest.mark.parametrize("preset", list(presets.PRESETS))
def test_help_fits_a_screen_and_shows_the_presets_own_values(preset, capsys):
    assert main(["train", "--preset", preset, "--help"]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    assert len(lines) <= 50 and max(len(x) for x in lines) <= 100
    flags = re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", text)
    listed = [f for f in flags if f not in ("--help", "--preset", "--help-all")]
    cfg = presets.preset(preset)
    from nerfkit.training.flags import flag_of, unused

    for name in unused(cfg):
        assert flag_of(name) not in listed and "--no-" + flag_of(name)[2:] not in listed, (preset, name)
    assert (f"--max-minutes {cfg.train.max_minutes:g}" if cfg.train.max_minutes else "--max-minutes -") in text
    if cfg.field.kind in ("mlp", "mip"):
        assert f"--width {cfg.field.width}" in text
    if cfg.field.kind == "splat":
        assert f"--capacity {cfg.splat.capacity}" in text and "--lr " not in text
    else:
        assert text.count("--lr ") == 1  # nothing printed twice


def test_help_all_explains_every_flag_the_preset_uses(capsys):
    from nerfkit.cli.help import setting_doc, shown
    from nerfkit.training.flags import flag_of

    for preset in presets.PRESETS:
        assert main(["train", "--preset", preset, "--help-all"]) == 0
        text = capsys.readouterr().out
        for name in shown(presets.preset(preset)):
            assert flag_of(name)[2:] in text and setting_doc(name)[:30] in " ".join(text.split()), (preset, name)



def test_every_value_help_shows_can_be_typed_back():
    """Each "--flag value" that --help prints for a preset parses back to that preset's setting: the words shown
    for an unset number (--bound auto, --devices all, --target-width -, --coarse auto) included."""
    from nerfkit.cli.help import _flag, shown
    from nerfkit.cli.train import parse_train_args

    for preset in presets.PRESETS:
        cfg = presets.preset(preset)
        for name in sorted(shown(cfg) - {"data.train_split", "data.val_split"}):  # these show what unset means
            section, field = name.split(".")
            argv = ["data", "--out", "run", "--preset", preset, *_flag(name, cfg).split()]
            parsed = getattr(getattr(parse_train_args(argv).cfg, section), field)
            if not isinstance(parsed, bool):  # a boolean's flag is the one that flips it
                assert parsed == getattr(getattr(cfg, section), field), (preset, name, argv)

def test_readme_and_help_agree_on_the_numbers_they_share():
    from nerfkit.cli.help import train_help
    from nerfkit.viewer.run import TRAINING_FRACTION

    docs = "\n".join(p.read_text() for p in [README, *sorted(README.with_name("docs").rglob("*.md"))])
    readme, helptext = (" ".join(t.split()) for t in (docs, train_help("ngp")))
    share = f"{TRAINING_FRACTION:.0%}"
    assert f"at most {share} of the wall time" in helptext
    assert f"below {share} of" in readme  # the viewer section
    minutes = presets.preset("ngp").train.max_minutes
    assert f"default budget: {minutes:g} minutes" in readme and f"{minutes:g} min of wall time" in helptext
