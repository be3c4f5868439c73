"""Step time of data-parallel training on N forced CPU devices against one device (issue 13).

    python benchmarks/parallel_step.py [--devices 2] [--steps 40] [--preset ngp]

Forces N host devices (XLA_FLAGS, before JAX starts), trains the preset on the procedural scene
(256 px) for --steps steps with --devices 1 and with --devices N in this one process, and prints the
median step time after compilation and the largest relative difference of the logged losses. On
2 CPU cores no speed-up is expected: the figure shows the overhead of the sharded step.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

p = argparse.ArgumentParser()
p.add_argument("--devices", type=int, default=2)
p.add_argument("--steps", type=int, default=40)
p.add_argument("--preset", default="ngp")
a = p.parse_args()
os.environ["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={a.devices}"

import numpy as np  # noqa: E402

from nerfkit.core.presets import preset  # noqa: E402
from nerfkit.core.viz import read_jsonl  # noqa: E402
from nerfkit.data.procedural.scene import make_scene  # noqa: E402
from nerfkit.training.trainer import Trainer  # noqa: E402


def run(root: Path, scene: Path, n: int) -> tuple[float, list[float]]:
    cfg = preset(a.preset)
    cfg.train.max_steps, cfg.train.log_every, cfg.train.val_every, cfg.train.devices = a.steps, 1, 10**6, n
    Trainer(scene, root / f"dev{n}", cfg, progress=False).run()
    rows = read_jsonl(root / f"dev{n}" / "metrics.jsonl")
    el = np.array([r["elapsed"] for r in rows])
    return float(np.median(np.diff(el[5:]))), [r["loss"] for r in rows]


with tempfile.TemporaryDirectory() as tmp:
    root = Path(tmp)
    scene = make_scene(root / "scene", size=256, n_train=20, n_val=2, n_test=1)
    t1, l1 = run(root, scene, 1)
    tn, ln = run(root, scene, a.devices)
diff = max(abs(x - y) / abs(x) for x, y in zip(l1, ln))
print(f"preset {a.preset}, {a.steps} steps on {os.cpu_count()} CPU cores:")
print(f"  1 device : {1000 * t1:.1f} ms/step (median after compilation)")
print(f"  {a.devices} devices: {1000 * tn:.1f} ms/step  ({tn / t1:.2f}x the one-device time)")
print(f"  largest relative loss difference: {diff:.2e}")
sys.exit(0)
