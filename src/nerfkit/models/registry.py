"""The methods, by `cfg.field.kind`: adding one is a module with a class following models/base.py
and one line here."""

from __future__ import annotations

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError
from nerfkit.models.base import Model
from nerfkit.models.mipnerf import MipNeRFModel
from nerfkit.models.nerf import NeRFModel
from nerfkit.models.ngp import NGPModel
from nerfkit.models.ngp_proposal import ProposalNGPModel
from nerfkit.models.splat.method import SplatModel

METHODS: dict[str, type] = {
    "mlp": NeRFModel,  # vanilla NeRF (presets seed, nerf, tiny)
    "mip": MipNeRFModel,  # mip-NeRF (preset mipnerf)
    "ngp": NGPModel,  # hash grid + occupancy grid (presets ngp, demo)
    "splat": SplatModel,  # 3D Gaussian splatting (preset splat)
}


# Methods whose settings pick between implementations of one interface: kind -> cfg -> the class to build.
VARIANTS = {
    "ngp": lambda cfg: ProposalNGPModel if cfg.sampler.resolved_sampling(cfg.field) == "proposal" else NGPModel,
}


def method_class(cfg: Config) -> type:
    """The class `cfg` builds: METHODS[cfg.field.kind], or for a method with VARIANTS the implementation its
    settings pick. ConfigError for an unknown kind."""
    try:
        method = METHODS[cfg.field.kind]
    except KeyError:
        raise ConfigError(f"field kind {cfg.field.kind!r} is not one of {', '.join(METHODS)}") from None
    return VARIANTS.get(cfg.field.kind, lambda _: method)(cfg)


def check(cfg: Config) -> type:
    """The method class of `cfg` after its own rules (its `check`, where it has one) and those of what it
    supports: ConfigError naming the setting otherwise."""
    cls = method_class(cfg)
    if cfg.field.scene_type == "unbounded" and not cls.supports.unbounded:
        able = [k for k, m in METHODS.items() if m.supports.unbounded]
        raise ConfigError(f"--scene-type unbounded needs a method that renders unbounded scenes ({', '.join(able)}: "
                          f"--preset ngp); the {cls.title} model samples a fixed [near, far] interval")
    rules = getattr(cls, "check", None)
    if rules is not None:
        rules(cfg)
    return cls


def unused(cfg: Config, capture=None) -> dict[str, str]:
    """{setting: why} of the settings the method of `cfg` leaves unread at their values (its `unused`)."""
    rule = getattr(method_class(cfg), "unused", None)
    return {} if rule is None else rule(cfg, capture)


def resolve_settings(cfg: Config, photos: bool, n_train: int, log=print) -> None:
    """Fill in the data-dependent defaults of the method's own settings in place (its `resolve_settings`, where it
    has one): `photos` says whether the capture is photos without masks, n_train counts its training photos."""
    rule = getattr(method_class(cfg), "resolve_settings", None)
    if rule is not None:
        rule(cfg, photos, n_train, log)


def build_model(cfg: Config) -> Model:
    """The model for `cfg.field.kind` (and, for a method with VARIANTS, the implementation its settings pick)."""
    return check(cfg)(cfg)
