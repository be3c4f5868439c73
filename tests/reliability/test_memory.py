"""Item 6: full-image rendering memory is set by --chunk, not by the image size.

A subprocess renders views of a tiny model with nerfkit.render.chunked.Renderer and reports,
for each, the peak resident memory above the memory it held just before (the kernel's
high-water mark is reset through /proc/self/clear_refs). Then:

* 200x200 -> 400x400 at the same chunk adds only the per-pixel arrays (rays, outputs,
  indices): at most PIXEL_BYTES per extra pixel, the bound README documents. Rendering
  the whole image at once would add ~120k rays x 16 samples x 32 wide activations, i.e.
  hundreds of MB;
* a 4x larger chunk at the same image size raises the peak by at least one more
  [chunk x samples x width] float32 activation;
* every peak is under the documented bound PIXEL_BYTES * H * W + chunk * samples * width * SAMPLE_BYTES.

glibc is asked to return large blocks to the system right away (MALLOC_MMAP_THRESHOLD_),
so the peaks measure what rendering needs, not what the allocator kept from earlier.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PIXEL_BYTES = 100  # README: about 60 bytes per pixel (measured ~50), at most 100
SAMPLE_BYTES = 32  # README: about 24 bytes per ray sample and unit of MLP width in a chunk (measured ~20)
MiB = 2**20

CHILD = textwrap.dedent(
    """
    import gc, json, sys
    import jax, numpy as np
    from nerfkit.rays.cameras import look_at
    from nerfkit.core.presets import preset
    from nerfkit.render.chunked import Renderer
    from nerfkit.models.registry import build_model

    def vm(key):
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) * 1024 for line in f if line.startswith(key))

    model = build_model(preset("tiny"))
    params, aux = model.init(jax.random.PRNGKey(0))
    pose = look_at(np.array([0.0, -4.0, 1.0]), np.zeros(3))
    peaks = []
    for size, chunk in json.loads(sys.argv[1]):
        renderer = Renderer(model, chunk)
        renderer.render_image(params, aux, pose, 64, 64, 80.0)  # compile, run one full chunk
        gc.collect()
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # reset the peak RSS to the current RSS
        base = vm("VmRSS")
        out = renderer.render_image(params, aux, pose, size, size, 1.2 * size)
        assert out["rgb"].shape == (size, size, 3) and np.isfinite(out["rgb"]).all()
        peaks.append(vm("VmHWM") - base)
        del out, renderer
        gc.collect()
    print(json.dumps(peaks))
    """
)


def _clear_refs_works() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


@pytest.mark.skipif(not Path("/proc/self/status").exists() or not _clear_refs_works(),
                    reason="needs Linux /proc/self/clear_refs to reset the peak RSS")
def test_render_peak_memory_scales_with_chunk_not_image_size(tmp_path, cached_env):
    cases = [(200, 4096), (400, 4096), (200, 16384)]
    env = {**cached_env, "MALLOC_MMAP_THRESHOLD_": "65536", "MALLOC_ARENA_MAX": "2"}
    script = tmp_path / "child.py"
    script.write_text(CHILD)
    proc = subprocess.run([sys.executable, str(script), json.dumps(cases)], capture_output=True, text=True, env=env,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    small, large, big_chunk = json.loads(proc.stdout.strip().splitlines()[-1])
    report = f"peaks above baseline: 200px {small / MiB:.1f} MiB, 400px {large / MiB:.1f} MiB, " \
             f"200px at 4x chunk {big_chunk / MiB:.1f} MiB"
    samples, width = 16, 32  # the tiny preset
    extra_pixels = 400**2 - 200**2
    # Image size: only the per-pixel arrays grow.
    assert large - small <= PIXEL_BYTES * extra_pixels, report
    # Chunk size: at least one more [chunk, samples, width] float32 activation.
    assert big_chunk - small >= (16384 - 4096) * samples * width * 4, report
    # The documented bound.
    for (size, chunk), peak in zip(cases, (small, large, big_chunk)):
        assert peak <= PIXEL_BYTES * size * size + SAMPLE_BYTES * chunk * samples * width, (size, chunk, report)
