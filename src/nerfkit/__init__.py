"""nerfkit: novel view synthesis from photos."""

from nerfkit.core.xla import default_flags as _default_xla_flags

_default_xla_flags()
