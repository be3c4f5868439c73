"""Data parallelism: one jitted training step over a mesh of devices (JAX's sharded jit, no pmap).

The step draws `batch_rays` rays (the global batch) as on one device; a sharding constraint splits
them along the mesh axis "data", so each of the N devices renders and differentiates B / N rays
(models that pack samples, NGPModel, split the packed samples instead: each device marches every ray,
cheap, and evaluates the field on 1/N of the samples, the cost),
while parameters, optimizer state, the occupancy grid and the training images are replicated. XLA
inserts the collectives (the gradient all-reduce). The math is the one-device step's: the same
rays, the same losses, up to the order of float sums.

    mesh = data_mesh(local_devices(n))     None for one device (the step is then unchanged)
    state = replicate(state, mesh)         before the first step
    x = shard_rays(x, mesh)                inside the step, on per-ray arrays [B, ...]
"""

from __future__ import annotations

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from nerfkit.errors import ConfigError

AXIS = "data"


def local_devices(n: int | None) -> list:
    """The first n local devices (None: all of them); ConfigError if there are fewer."""
    devices = jax.local_devices()
    if n is None:
        return devices
    if not 1 <= n <= len(devices):
        raise ConfigError(f"--devices {n}: this process sees {len(devices)} device(s) "
                          f"({devices[0].platform}); pick 1..{len(devices)}")
    return devices[:n]


def data_mesh(devices: list) -> Mesh | None:
    """A 1-D mesh over devices along AXIS, or None for a single device."""
    return Mesh(np.array(devices), (AXIS,)) if len(devices) > 1 else None


def check_batch(batch: int, mesh: Mesh | None, flag: str = "--batch-rays") -> None:
    """ConfigError unless the global batch splits evenly over the mesh."""
    n = 1 if mesh is None else mesh.devices.size
    if batch % n:
        raise ConfigError(f"{flag} {batch} does not split over {n} devices; use a multiple of {n}")


def replicate(tree, mesh: Mesh | None):
    """tree with every array copied to every device of the mesh (unchanged without a mesh)."""
    return tree if mesh is None else jax.device_put(tree, NamedSharding(mesh, PartitionSpec()))


def shard_rays(x, mesh: Mesh | None):
    """Constrain per-ray (or per-sample) arrays x [B, ...] (a pytree; None leaves stay None) to be split
    along their first axis over the mesh."""
    if mesh is None:
        return x
    return jax.lax.with_sharding_constraint(x, NamedSharding(mesh, PartitionSpec(AXIS)))


def describe(batch: int, mesh: Mesh | None, split: str = "rays", samples: int | None = None) -> str:
    """One line for the log: the devices and the global batch (of rays, or of packed samples)."""
    if mesh is None:
        d = jax.local_devices()[0]
        return f"1 device ({d.platform}), batch {batch} rays"
    n = mesh.devices.size
    what = (f"global batch {batch} rays = {batch // n} per device x {n}" if split == "rays" else
            f"global batch {batch} rays, their {samples} packed samples split {samples // n} per device x {n}")
    return f"data parallel over {n} {mesh.devices.flat[0].platform} devices: {what}"
