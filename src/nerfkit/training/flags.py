"""Which settings each model reads, so that a flag is either used or refused, never silently ignored.

A setting is named "section.field" (e.g. "field.width"); its command-line flag is --field-name
(--no-field-name for a boolean's False). `unused(cfg, capture)` lists the settings the configured
model will not read, with the reason:

    by kind       field.depth, field.width, ... are read by the MLP fields (mlp, mip) only;
                  field.hash_*, field.bound, sampler.occ_*, sampler.march_steps, ... by ngp only;
                  the ray and NeRF-optimiser settings (near, far, batch_rays, lr, ...) by the fields only,
                  splat.* by the Gaussian splats (splat) only
    by value      what each method leaves unread at the values given (its `unused`, models/registry.py):
                  field.l_xyz without positional encoding (--no-pe), field.l_dir without view
                  directions, train.precrop_frac without a warm-up (--precrop-steps 0),
                  sampler.occ_warmup_decay without a warm-up (--occ-warmup 0), sampler.proposal_samples
                  and field_samples where the occupancy grid places the samples; here, data.target_width
                  when --downscale is given
    by the data   data.holdout_every for captures with their own splits (Blender, *_filenames), data.masks
                  for captures without object masks

`refuse_unused` turns the ones the user gave explicitly into one ConfigError naming the flag and
the reason. Every other setting is read by every model (tests/training/test_flags.py proves both sides for
every flag of `nerfkit train` and every preset).
"""

from __future__ import annotations

import dataclasses

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError
from nerfkit.core.presets import PRESETS

SECTIONS = tuple(Config.sections())  # ("data", "field", "sampler", "train", "splat")


def by_kind() -> dict[str, frozenset[str]]:
    """{setting: the method kinds that read it} for every setting some method does not read (a method
    declares what it reads in `reads`, models/base.py; a setting no method lists is read by all)."""
    from nerfkit.models.registry import (
        METHODS,  # deferred: the CLI parses flags before JAX loads
    )

    listed = set().union(*(m.reads for m in METHODS.values()))
    return {n: frozenset(k for k, m in METHODS.items() if n in m.reads) for n in sorted(listed)}


# Settings filled in from the data (resolve.py; the --init file's SH degree: models/splat/method.py), never from
# the command line.
FROM_DATA = frozenset({"field.appearance_count", "field.ndc_frame", "field.ndc_near", "field.ndc_extent",
                       "data.undistort", "splat.init_sh_degree"})


def kind_name(kind: str) -> str:
    """The method's name in messages: "hash-grid (ngp)"."""
    from nerfkit.models.registry import (
        METHODS,  # deferred: the CLI parses flags before JAX loads
    )

    return METHODS[kind].title


def setting_names() -> list[str]:
    """Every "section.field" of a Config, in declaration order."""
    cfg = Config()
    return [f"{s}.{f.name}" for s in SECTIONS for f in dataclasses.fields(getattr(cfg, s))]


def flag_of(name: str) -> str:
    """The flag of a setting: "field.l_xyz" -> "--l-xyz"."""
    return "--" + name.split(".", 1)[1].replace("_", "-")


def setting_of_flag(flag: str) -> str | None:
    """The setting a flag sets ("--no-pe" -> "field.pe", "--l_xyz=4" -> "field.l_xyz"), or None."""
    key = flag.split("=", 1)[0].lstrip("-").replace("_", "-")
    by_flag = {flag_of(n)[2:]: n for n in setting_names()}
    if key in by_flag:
        return by_flag[key]
    if key.startswith("no-") and key[3:] in by_flag:
        return by_flag[key[3:]]
    return None


def explicit_settings(argv: list[str]) -> dict[str, str]:
    """{setting: the flag as typed} of every setting flag in argv."""
    out = {}
    for a in argv:
        if a.startswith("--"):
            name = setting_of_flag(a)
            if name is not None:
                out[name] = a.split("=", 1)[0]
    return out


def presets_using(name: str) -> list[str]:
    """The presets whose model reads setting `name`."""
    kinds = by_kind().get(name)
    return [p for p, make in PRESETS.items() if kinds is None or make().field.kind in kinds]


def unused(cfg: Config, capture=None, where: str = "this run") -> dict[str, str]:
    """{setting: why the configured model does not read it}: the settings its method does not list in
    `reads`, those its method leaves unread at these values (its `unused`, models/registry.py); with a
    capture (data/capture.Capture), also the data settings it makes moot. `where` names the model in the
    reasons ("--preset ngp")."""
    from nerfkit.models import registry  # deferred: the CLI parses flags before JAX loads

    d = cfg.data
    kind = cfg.field.kind
    out = {n: f"the {kind_name(kind)} model of {where} does not read it" for n, kinds in by_kind().items()
           if kind not in kinds}
    out.update(registry.unused(cfg, capture))
    if d.downscale is not None:
        out["data.target_width"] = "--downscale sets the image size"
    if capture is not None:
        if capture.own_splits:
            out["data.holdout_every"] = f"the {capture.format} capture {capture.root} has its own splits"
        if not capture.has_masks and not capture.masks_dropped:
            out["data.masks"] = f"the capture {capture.root} has no object masks"
    return out


def refuse_unused(cfg: Config, given: dict[str, str], where: str, capture=None) -> None:
    """ConfigError for the first explicitly given setting (`given`: setting -> flag as typed) that the
    model or the data will not read; `where` names the model in the message ("--preset ngp")."""
    moot = unused(cfg, capture, where)
    table = by_kind()
    for name, typed in given.items():
        if name in FROM_DATA:
            raise ConfigError(f"{typed}: set from the data, not a flag; drop it")
        if name in moot:
            hint = ""
            if name in table and cfg.field.kind not in table[name]:
                hint = f", or pick a preset that uses it: {', '.join(presets_using(name))}"
            raise ConfigError(f"{typed} has no effect: {moot[name]}; drop it{hint}")


def refuse_family_switch(cfg: Config, given: dict[str, str], preset: str | None) -> None:
    """ConfigError when --kind moves a run between method families (the preset's Gaussian splats and a
    radiance field, or back): their settings have nothing in common; the preset picks the family."""
    if "field.kind" not in given or preset not in PRESETS:
        return
    from nerfkit.models import registry  # deferred: the CLI parses flags before JAX loads

    ours, theirs = registry.method_class(PRESETS[preset]()).supports, registry.method_class(cfg).supports
    if ours.renders_images != theirs.renders_images:  # rasterised primitives against rays through a field
        raise ConfigError(f"{given['field.kind']} {cfg.field.kind} with --preset {preset}: the preset's method "
                          f"and the {kind_name(cfg.field.kind)} model are different families; pick the preset instead "
                          f"(--preset splat, --preset ngp, ...) and drop {given['field.kind']}")


def describe_model(cfg: Config) -> str:
    """One line naming the model that runs, with the settings it reads (and only those): the method's own
    describe(cfg)."""
    from nerfkit.models.registry import (
        METHODS,  # deferred: the CLI parses flags before JAX loads
    )

    return METHODS[cfg.field.kind].describe(cfg)


def describe_budget(cfg: Config) -> str:
    """The training budget in words."""
    t = cfg.train
    if t.max_minutes is None:
        return f"{t.max_steps} steps"
    return f"{t.max_minutes:g} min of wall time or {t.max_steps} steps, whichever comes first"
