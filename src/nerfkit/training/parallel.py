"""Data parallelism: one jitted training step over a mesh of devices (JAX's sharded jit, no pmap).

The step draws `batch_rays` rays (the global batch) as on one device; a sharding constraint splits
them along the mesh axis "data", so each of the N devices renders and differentiates B / N rays
(models that pack samples, NGPModel, split the packed samples instead: each device marches every ray,
cheap, and evaluates the field on 1/N of the samples, the cost),
while parameters, optimizer state, the occupancy grid and the training images are replicated. XLA
inserts the collectives (the gradient all-reduce). The math is the one-device step's: the same
rays, the same losses, up to the order of float sums.

    mesh = data_mesh(mesh_devices(n))      None for one device (the step is then unchanged)
    state = replicate(state, mesh)         before the first step
    x = shard_rays(x, mesh)                inside the step, on per-ray arrays [B, ...]

Several hosts (multi-controller JAX): `init_distributed()` joins the processes named by the
environment (NERFKIT_COORDINATOR=host:port, NERFKIT_NUM_PROCESSES, NERFKIT_PROCESS_ID; or a SLURM
job step with several tasks, whose variables JAX reads itself) before JAX starts. Every process
loads the same data, runs the same jitted step on a mesh over the devices of all processes, and
renders and differentiates only its own devices' share of each step's rays; parameters stay
replicated. Only process 0 writes the run folder (`is_primary`); decisions that end the loop
(time budget, Ctrl-C) are taken by process 0 and broadcast (`agree`), so every process runs the
same number of steps.
"""

from __future__ import annotations

import os

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from nerfkit.core.errors import ConfigError

AXIS = "data"
ENV = ("NERFKIT_COORDINATOR", "NERFKIT_NUM_PROCESSES", "NERFKIT_PROCESS_ID")


def init_distributed() -> int:
    """Join a multi-process run if the environment names one (see the module doc); returns the number of
    processes (1: nothing to join). Must run before anything starts JAX's backends."""
    coordinator = os.environ.get(ENV[0], "").strip()
    if coordinator:
        try:
            n, pid = int(os.environ[ENV[1]]), int(os.environ[ENV[2]])
        except (KeyError, ValueError):
            raise ConfigError(f"{ENV[0]}={coordinator} needs integer {ENV[1]} (processes) and "
                              f"{ENV[2]} (0..N-1)") from None
        if not (n >= 1 and 0 <= pid < n):
            raise ConfigError(f"{ENV[2]}={pid} must be in 0..{ENV[1]}-1 = {n - 1}")
        jax.distributed.initialize(coordinator_address=coordinator, num_processes=n, process_id=pid)
    elif "SLURM_JOB_ID" in os.environ and int(os.environ.get("SLURM_STEP_NUM_TASKS", "1")) > 1:
        jax.distributed.initialize()  # JAX's SLURM cluster detection: coordinator, count and id from SLURM
    return jax.process_count()


def is_primary() -> bool:
    """Whether this process writes the run folder and logs (process 0)."""
    return jax.process_index() == 0


def agree(flag: bool) -> bool:
    """Process 0's `flag` on every process (a broadcast when there are several; flag itself otherwise)."""
    if jax.process_count() == 1:
        return bool(flag)
    from jax.experimental import multihost_utils

    return bool(multihost_utils.broadcast_one_to_all(np.int32(bool(flag))))


def host_copy(tree):
    """tree with every replicated jax.Array copied to host memory (numpy), so that one process can render or
    save it without the others; unchanged with a single process (its arrays are all addressable)."""
    if jax.process_count() == 1:
        return tree
    return jax.tree_util.tree_map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x, tree)


def local_devices(n: int | None) -> list:
    """The first n local devices (None: all of them); ConfigError if there are fewer."""
    devices = jax.local_devices()
    if n is None:
        return devices
    if not 1 <= n <= len(devices):
        raise ConfigError(f"--devices {n}: this process sees {len(devices)} device(s) "
                          f"({devices[0].platform}); pick 1..{len(devices)}")
    return devices[:n]


def mesh_devices(n: int | None) -> list:
    """The first n local devices (None: all) of every process, process by process: the devices one step
    runs on. With one process, local_devices(n)."""
    local = local_devices(n)
    if jax.process_count() == 1:
        return local
    return [d for p in range(jax.process_count())
            for d in sorted((d for d in jax.devices() if d.process_index == p), key=lambda d: d.id)[:len(local)]]


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
        if split == "samples":
            return f"1 device ({d.platform}), up to {batch} rays per step (as many as fit {samples} samples)"
        return f"1 device ({d.platform}), batch {batch} rays"
    n = mesh.devices.size
    hosts = jax.process_count()
    what = (f"global batch {batch} rays = {batch // n} per device x {n}" if split == "rays" else
            f"global batch {batch} rays, their {samples} packed samples split {samples // n} per device x {n}")
    where = f" in {hosts} processes" if hosts > 1 else ""
    return f"data parallel over {n} {mesh.devices.flat[0].platform} devices{where}: {what}"
