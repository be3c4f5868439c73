"""The methods, by `cfg.field.kind`: adding one is a module with a class following models/base.py
and one line here."""

from __future__ import annotations

from nerfkit.core.config import Config
from nerfkit.core.errors import ConfigError
from nerfkit.models.base import Model
from nerfkit.models.nerf import MipNeRFModel, NeRFModel, NGPModel
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


def build_model(cfg: Config) -> Model:
    """The model for `cfg.field.kind` (and, for a method with VARIANTS, the implementation its settings pick)."""
    try:
        method = METHODS[cfg.field.kind]
    except KeyError:
        raise ConfigError(f"field kind {cfg.field.kind!r} is not one of {', '.join(METHODS)}") from None
    return VARIANTS.get(cfg.field.kind, lambda _: method)(cfg)(cfg)
