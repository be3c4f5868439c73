"""`nerfkit train --help`: the flags a newcomer needs first, then the rest in groups named for people, with
the chosen preset's own values and only the settings that preset's model reads (flags.unused). The
descriptions are the dataclasses' field docstrings (cli_args.TrainArgs, config.*Config), so help, parser
and config cannot drift apart; --help-all prints every description.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import textwrap

from nerfkit.cli.args import TrainArgs
from nerfkit.core.config import Config
from nerfkit.core.presets import PRESET_HELP, PRESETS
from nerfkit.training.flags import (
    FROM_DATA,
    describe_budget,
    describe_model,
    flag_of,
    kind_name,
    unused,
)
from nerfkit.viewer.run import TRAINING_FRACTION

FIRST = ("data.downscale", "train.max_minutes", "train.max_steps")
TITLES = {"field": "Model", "sampler": "Sampling", "splat": "Splats"}  # a section not named here: its own name
GROUPS = {
    "Data": ("data.train_split", "data.val_split", "data.target_width", "data.background", "data.format",
             "data.masks", "data.holdout_every"),
    **{TITLES.get(name, name.title()): tuple(f"{name}.{f.name}" for f in dataclasses.fields(cls))
       for name, cls in Config.sections().items() if name not in ("data", "train")},
    "Training": ("train.lr", "train.lr_decay_steps", "train.lr_decay_rate", "train.adam_b2", "train.adam_eps",
                 "train.batch_rays", "train.seed", "train.precrop_steps", "train.precrop_frac", "train.devices",
                 "train.max_bad_steps", "train.pose_refine"),
    "Output": ("train.val_every", "train.val_views", "train.val_max_fraction", "train.ckpt_every",
               "train.keep_ckpts", "train.log_every", "train.chunk"),
}
WIDTH = 100


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """{field name: the docstring under it} of a dataclass (the string literal after each annotated field)."""
    body = ast.parse(textwrap.dedent(inspect.getsource(cls))).body[0].body
    docs = {}
    for a, b in zip(body, body[1:]):
        if isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name) and isinstance(b, ast.Expr) \
                and isinstance(b.value, ast.Constant) and isinstance(b.value.value, str):
            docs[a.target.id] = " ".join(b.value.value.split())
    return docs


def setting_doc(name: str) -> str:
    section, field = name.split(".")
    return field_docs(type(getattr(Config(), section))).get(field, "")


# What an unset (None) value means, per setting.
UNSET = {"data.train_split": "train", "data.val_split": "val|test", "data.downscale": "auto", "data.target_width": "-",
         "train.max_minutes": "-", "train.devices": "all", "splat.init": "-"}


def _flag(name: str, cfg: Config) -> str:
    """The flag with the preset's value ("--lr 0.01"); for a boolean, the flag that changes it."""
    section, field = name.split(".")
    v = getattr(getattr(cfg, section), field)
    flag = flag_of(name)
    if isinstance(v, bool):
        return flag if not v else "--no-" + flag[2:]
    if v is None:
        return f"{flag} {UNSET.get(name, 'auto')}"
    return f"{flag} {v:g}" if isinstance(v, float) else f"{flag} {v}"


def shown(cfg: Config) -> set[str]:
    """The settings this preset's model reads (the others are refused, so they are not listed)."""
    return {n for names in GROUPS.values() for n in names} - set(unused(cfg)) - FROM_DATA


def _wrap(text: str, indent: str, first: str = "") -> list[str]:
    return textwrap.wrap(text, WIDTH, initial_indent=first or indent, subsequent_indent=indent,
                         break_on_hyphens=False, break_long_words=False) or [first]


def _pack(items: list[str], indent: str = "    ") -> list[str]:
    """Items ("--lr 0.01") on lines of at most WIDTH characters, never split."""
    lines, cur = [], indent
    for item in items:
        if cur.strip() and len(cur) + 2 + len(item) > WIDTH:
            lines.append(cur)
            cur = indent
        cur += ("  " if cur.strip() else "") + item
    return lines + [cur]


def train_help(preset: str, full: bool = False) -> str:
    """The help text of `nerfkit train --preset PRESET [--help | --help-all]`."""
    cfg = PRESETS[preset]()
    args = field_docs(TrainArgs)
    keep = shown(cfg)
    lines = ["usage: nerfkit train DATA --out RUN [--preset P] [--max-minutes M] [flags]", "",
             "Train a radiance field on a capture folder and write a run folder.", "",
             *_wrap(PRESET_HELP[preset], "    ", f"preset {preset}: "), *_wrap(describe_model(cfg), "    ", "  model: "),
             f"  budget: {describe_budget(cfg)}", ""]
    first = [("DATA", "capture folder (Blender, nerfstudio, LLFF or COLMAP); `nerfkit process-data` makes one from "
                      "photos or a video"),
             ("--out RUN", args["out"]),
             ("--preset P", "ngp (default) | " + " | ".join(p for p in PRESETS if p != "ngp")
              + "; `nerfkit train --preset P --help` shows that preset's flags and values"),
             *[(_flag(n, cfg), setting_doc(n)) for n in FIRST],
             ("--viewer", f"watch it train in the browser (rendering takes at most {TRAINING_FRACTION:.0%} of the "
                          f"wall time; it stays open after)"),
             ("--resume / --overwrite", "continue the run in --out / start it again there (its run files removed)")]
    for flag, doc in first:
        doc = doc.split(". ")[0].rstrip(".") if not full else doc
        lines += _wrap(doc, " " * 26, f"  {flag:<23} " if len(flag) < 24 else f"  {flag}\n" + " " * 26)
    for group, names in GROUPS.items():
        names = [n for n in names if n in keep and n not in FIRST]
        title = f"{group}, {kind_name(cfg.field.kind)}" if group in ("Model", "Sampling") else group
        if not names:
            continue
        lines += ["", f"{title}:"]
        if full:
            for n in names:
                lines += _wrap(setting_doc(n), " " * 6, f"  {_flag(n, cfg)}: ")
        else:
            lines += _pack([_flag(n, cfg) for n in names])
    more = ["--progress/--no-progress", "--viewer-host 127.0.0.1", "--viewer-port 7007"]
    lines += ["", "Also: " + ", ".join(more),
              "Values shown are the preset's; each flag sets one. --help-all explains every flag."
              if not full else "Values shown are the preset's; each flag sets one."]
    return "\n".join(lines)
