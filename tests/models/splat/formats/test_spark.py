"""A third-party web renderer opens the splat files nerfkit writes and draws them as nerfkit does: Spark (npm
@sparkjsdev/spark 2.2.0 on three.js 0.187.0, pinned in tests/web) in headless Chromium (tests/spark_splats.py:
a loopback server, nothing from the network), against nerfkit's rasteriser on the same file as nerfkit reads it
back, from the same pinhole camera, both on white.

The shared 200-step run (conftest.splat_run) is exported through the CLI to .ply, .spz and .splat and each file
drawn from training view 0 at 192 x 192 (the run's field of view; it trains at 32 px). Measured (SwiftShader
WebGL2, Chromium's CPU renderer; Spark set to nerfkit's kernel, spark_splats.NERFKIT_MATCH):

    .ply  51.3 dB   .spz  50.9 dB   .splat  50.0 dB     (views 0, 3, 6: 49.4-51.3 dB)
    the other axis convention (the pose turned 180 degrees about x): 11.8 dB for each
    Spark's own defaults (what a page gets without options): 45.4-46.0 dB

so the floor is 40 dB (the issue's bar is 30; 9 dB under what was measured) for Spark set to nerfkit's kernel,
38 dB for Spark's defaults (its Mip-Splatting filter dims the smallest Gaussians: 22.7-24.1 dB at the run's own
32 px, where they are a pixel wide, which is why the test draws at 192), and a wrong camera must fall under 20 dB.
The axes: Spark draws every file's coordinates as stored, so a .spz (RUB: nerfkit turns it by F = diag(1, -1, -1))
is seen from F @ c2w and a .ply or .splat from c2w (spark_splats.AXIS_RULE; its docstring has the measurement).

The run has no view-dependent colour yet (SH bands start later in training), so a second test draws Gaussians with
strong SH bands 1-3 (test_ply.gaussians) from .ply and .spz, whose bands nerfkit turns with the axes: Spark
scores 36.6-39.9 dB against nerfkit's degree-3 render (its SH are quantised to 7 bits and fewer) and 21.5-22.3
against its degree-0 one; floors 33 dB and 8 dB above degree 0.

Each comparison (nerfkit left, Spark right) is written as a PNG into the test's tmp_path and copied into the
folder $NERFKIT_SPARK_SCREENSHOTS names, when set. One browser serves the module's tests. Run time: 36 s on two
busy cores, 16 s of it training the shared run (made once per session for all the tests that use it).
"""

from __future__ import annotations

import pytest
from spark_splats import AXIS_RULE, F, SparkPage, spark_vs_nerfkit
from splat_pages import keep, training_view
from sh_scene import degree_zero, sh_scene
from web_tools import node_module

from nerfkit.cli.main import main

FORMATS = (".ply", ".spz", ".splat")
SIZE = 192  # px: Spark and nerfkit agree to ~50 dB here; at the run's 32 px Spark's defaults dim 1-px Gaussians
FLOOR = 40.0  # dB, Spark set to nerfkit's kernel (measured 49.4-51.3)
FLOOR_DEFAULTS = 38.0  # dB, Spark's defaults (measured 45.1-46.3)
WRONG_CEILING = 20.0  # dB, the other axis convention (measured 11.2-12.7)
SCREENSHOTS = "NERFKIT_SPARK_SCREENSHOTS"  # the folder (an environment variable) keep() copies the comparisons to


@pytest.fixture(scope="module")
def exported(splat_run, tmp_path_factory):
    """{extension: the shared run exported to it by `nerfkit export splat`}, and the run."""
    _, run = splat_run
    out = tmp_path_factory.mktemp("spark_exports")
    files = {}
    for ext in FORMATS:
        files[ext] = out / f"scene{ext}"
        assert main(["export", "splat", str(run), "--out", str(files[ext])]) == 0
    return files, run


@pytest.fixture(scope="module")
def spark_page(tmp_path_factory):
    """page(chromium): one SparkPage for the module's tests (a browser start and Spark's first render cost ~5 s),
    opened by the first test that asks (after its skips) and closed after the last."""
    pages = {}

    def page(binary: str) -> SparkPage:
        if binary not in pages:
            pages[binary] = SparkPage(binary, tmp_path_factory.mktemp("spark_profile"), (SIZE, SIZE))
        return pages[binary]

    yield page
    for p in pages.values():
        p.close()


@pytest.mark.parametrize("ext", FORMATS)
def test_spark_draws_the_exported_file_like_nerfkit(chromium, spark_page, exported, tmp_path, ext):
    node_module("@sparkjsdev/spark")
    files, run = exported
    c2w, cam = training_view(run, 0, SIZE)
    page = spark_page(chromium)
    png = tmp_path / f"spark_{ext[1:]}.png"
    right = spark_vs_nerfkit(page, files[ext], c2w, cam, png=png)
    keep(png, SCREENSHOTS)
    wrong = spark_vs_nerfkit(page, files[ext], c2w, cam, flip=F @ AXIS_RULE[ext])  # the other convention
    default = spark_vs_nerfkit(page, files[ext], c2w, cam, options={})  # Spark as a page gets it
    assert right["nerfkit"].std() > 0.05, "a blank reference image: a bad test camera"
    print(f"Spark vs nerfkit, {ext}: {right['psnr']:.2f} dB ({right['frames']} renders), other axes "
          f"{wrong['psnr']:.2f} dB, Spark's defaults {default['psnr']:.2f} dB, {cam.width}x{cam.height}")
    assert right["psnr"] >= FLOOR, right["psnr"]
    assert wrong["psnr"] <= WRONG_CEILING, wrong["psnr"]
    assert default["psnr"] >= FLOOR_DEFAULTS, default["psnr"]


@pytest.mark.parametrize("ext", (".ply", ".spz"))
def test_spark_draws_the_view_dependent_colour(chromium, spark_page, tmp_path, ext):
    from nerfkit.core.metrics import psnr

    node_module("@sparkjsdev/spark")
    g, cam, poses = sh_scene(tmp_path / f"sh{ext}", SIZE)
    page = spark_page(chromium)
    for k, c2w in enumerate(poses):  # in front, and from behind
        png = tmp_path / f"spark_sh_{ext[1:]}_{k}.png"
        got = spark_vs_nerfkit(page, tmp_path / f"sh{ext}", c2w, cam, png=png)
        keep(png, SCREENSHOTS)
        flat = float(psnr(got["spark"], degree_zero(g, c2w, cam)))
        print(f"Spark vs nerfkit, {ext} with SH, view {k}: {got['psnr']:.2f} dB (degree 0: {flat:.2f} dB)")
        assert got["psnr"] >= 33.0, got["psnr"]
        assert got["psnr"] >= flat + 8.0, (got["psnr"], flat)
