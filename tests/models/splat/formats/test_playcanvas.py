"""A third-party web renderer draws the glTF and .sog files nerfkit writes (KHR_gaussian_splatting, formats/gltf.py;
PlayCanvas's SOG, formats/sog.py) as nerfkit does: the PlayCanvas engine (npm playcanvas 2.23.3, pinned in tests/web) in headless Chromium
(tests/playcanvas_splats.py: a loopback server, nothing from the network; the engine's own glTF loader and its
default settings, as a page that embeds the file gets them), against nerfkit's rasteriser on the same file as
nerfkit reads it back, from the same pinhole camera, both on white.

The shared 200-step run (conftest.splat_run; 1,000 Gaussians in its export) is exported through the CLI to .glb and
drawn from training view 0 at 192 x 192 (the run's field of view; it trains at 32 px). Measured (SwiftShader WebGL2,
Chromium's CPU renderer), training views 0, 3 and 6, on the run as 3DGS's learning rates left it (greys; with today's
rates it renders the scene's colours, and view 0 measures 36.3 dB against nerfkit, 48.5 (.glb) and 45.4 (.sog)
against playcanvas_model):

    PlayCanvas vs nerfkit                       38.4-38.6 dB  (playcanvas_splats.PRECISE: 38.6-39.0)
    PlayCanvas vs playcanvas_model              51.4-51.6 dB  (PRECISE: 56.5-56.8)
    the other axis convention (c2w, not F c2w)  11.3-12.8 dB
    at the run's own 32 px, vs nerfkit          23.9-25.0 dB  (vs playcanvas_model 49.9-51.7)

PlayCanvas's kernel is not nerfkit's (playcanvas_splats' docstring, from its shaders): its dilation is 0.075 px^2,
not 0.3 (it adds 0.3 to a covariance measured in half pixels), and its Gaussian is renormalised to vanish at
sqrt(8) sigma, thinning the tails (-12 % at 2 sigma); both are in its shaders, not settings. Those two rules on
nerfkit's own projection (playcanvas_model) account for all but 51-57 dB of what PlayCanvas draws (the rest is its
work-buffer packing and 8-bit blending), at 32 px as at 192, and cost what separates it from nerfkit: mostly the
tails at 192 px, mostly the dilation at 32 px (Gaussians about a pixel wide, which is why the test draws at 192).
So the floors: 34 dB against nerfkit (the issue's bar is 30; 2.3 dB under today's 36.3), 43 dB against the
model (2.4 under the .sog's 45.4, and 7 over nerfkit's own rules), and a wrong camera must fall under 20 dB. The
axes: PlayCanvas draws the glTF node as stored (+Y up, no turn), so the capture seen from c2w is seen in the .glb
from F @ c2w (F = diag(1, -1, -1)).

The run has no view-dependent colour yet, so a second test writes Gaussians with strong SH bands 1-3
(test_ply.gaussians) to .glb and .gltf at degree 3: PlayCanvas reads SH_DEGREE_1..3 from glTF and draws them
(evaluated per Gaussian from the camera's centre, as nerfkit; coefficients packed to 11/10/11 bits): 38.3 dB
against nerfkit's degree-3 render, 21.0-21.9 against its degree-0 one, 43.7-44.0 against playcanvas_model; floors
34 dB, 8 dB above degree 0, and 40 dB.

The same run exported to .sog (PlayCanvas's own format, loaded as a 'gsplat' asset, in the capture's axes): 38.9 dB
against nerfkit's render of the file as read back, 52.7 against playcanvas_model, 11.9 with glTF's turn; the SH
scene as .sog (every Gaussian its own palette entry) 38.2-38.4 dB (degree 0: 21.0-22.0), 43.8-44.3 against the
model. The .glb's floors hold for both.

Each comparison (nerfkit, PlayCanvas, the model) is written as a PNG into the test's tmp_path and copied into the
folder $NERFKIT_PLAYCANVAS_SCREENSHOTS names, when set. One browser serves the module's tests. Run time: 37-43 s
on two busy cores, ~19 s of it training and exporting the shared run (made once per session for all the tests that
use it); the tests themselves ~15 s (the browser's start and first render ~5 s).
"""

from __future__ import annotations

import numpy as np
import pytest
from playcanvas_splats import PlayCanvasPage, playcanvas_vs_nerfkit
from splat_pages import keep, training_view
from sh_scene import degree_zero, sh_scene
from web_tools import node_module

from nerfkit.cli.main import main

SIZE = 192  # px: at the run's 32 px PlayCanvas's 0.075 px^2 dilation leaves 1-px Gaussians far thinner
FLOOR = 34.0  # dB against nerfkit (measured 36.3; 38.4-38.6 with 3DGS's learning rates)
# dB against playcanvas_model, which leaves out the engine's quantisation and 8-bit blending: measured 48.5 (.glb)
# and 45.4 (.sog) on the shared run, 51.4-51.6 on its washed-out greys with 3DGS's learning rates; between that and
# the 36.3 that nerfkit's own rules (0.3 px^2 dilation, the 0.99 clamp) score against PlayCanvas
MODEL_FLOOR = 43.0
WRONG_CEILING = 20.0  # dB, the other axis convention (measured 11.3-12.8)
SH_FLOOR, SH_MODEL_FLOOR, SH_OVER_FLAT = 34.0, 40.0, 8.0  # measured 38.3, 43.7-44.0, 16.4-17.4
SCREENSHOTS = "NERFKIT_PLAYCANVAS_SCREENSHOTS"  # the folder (an environment variable) keep() copies the comparisons to


@pytest.fixture(scope="module")
def exported(splat_run, tmp_path_factory):
    """export(suffix) -> (the shared run exported by `nerfkit export splat` to scene<suffix>, once per suffix; the
    run)."""
    _, run = splat_run
    files = {}

    def export(suffix: str):
        if suffix not in files:
            files[suffix] = tmp_path_factory.mktemp("playcanvas_export") / f"scene{suffix}"
            assert main(["export", "splat", str(run), "--out", str(files[suffix])]) == 0
        return files[suffix], run

    return export


@pytest.fixture(scope="module")
def playcanvas_page(tmp_path_factory):
    """page(chromium): one PlayCanvasPage for the module's tests (a browser start and the engine's first render
    cost ~5 s), opened by the first test that asks (after its skips) and closed after the last."""
    pages = {}

    def page(binary: str) -> PlayCanvasPage:
        if binary not in pages:
            pages[binary] = PlayCanvasPage(binary, tmp_path_factory.mktemp("playcanvas_profile"), (SIZE, SIZE))
        return pages[binary]

    yield page
    for p in pages.values():
        p.close()


# the other axis convention, for each file: the .glb is drawn from F c2w (glTF is +Y up), so the pose as given is
# wrong; the .sog holds the capture's axes, so glTF's turn F is wrong
WRONG_TURN = {".glb": np.eye(4), ".sog": np.diag([1.0, -1.0, -1.0, 1.0])}


# Both files are held to the same floors: PlayCanvas draws them with one kernel. Against nerfkit the .sog's
# quantisation costs nothing measurable at this size (36.35 dB against the .glb's 36.25); against the model, which
# leaves the engine's own quantisation out, the .sog scores 3 dB under the .glb (45.4 against 48.5).
@pytest.mark.parametrize("suffix", (".glb", ".sog"))
def test_playcanvas_draws_the_exported_file_like_nerfkit(chromium, playcanvas_page, exported, tmp_path, suffix):
    node_module("playcanvas")
    file, run = exported(suffix)
    c2w, cam = training_view(run, 0, SIZE)
    page = playcanvas_page(chromium)
    png = tmp_path / f"playcanvas_{suffix[1:]}.png"
    right = playcanvas_vs_nerfkit(page, file, c2w, cam, png=png, model=True)
    keep(png, SCREENSHOTS)
    wrong = playcanvas_vs_nerfkit(page, file, c2w, cam, flip=WRONG_TURN[suffix])
    assert right["nerfkit"].std() > 0.05, "a blank reference image: a bad test camera"
    assert right["playcanvas"].std() > 0.05, "PlayCanvas drew nothing"
    print(f"PlayCanvas vs nerfkit, {suffix}: {right['psnr']:.2f} dB ({right['frames']} renders), vs PlayCanvas's "
          f"rules {right['psnr_model']:.2f} dB, other axes {wrong['psnr']:.2f} dB, {cam.width}x{cam.height}")
    assert right["psnr"] >= FLOOR, right["psnr"]
    assert right["psnr_model"] >= MODEL_FLOOR, right["psnr_model"]
    assert wrong["psnr"] <= WRONG_CEILING, wrong["psnr"]


@pytest.mark.parametrize("ext", (".glb", ".gltf", ".sog"))
def test_playcanvas_draws_the_view_dependent_colour(chromium, playcanvas_page, tmp_path, ext):
    from nerfkit.core.metrics import psnr

    node_module("playcanvas")
    g, cam, poses = sh_scene(tmp_path / f"sh{ext}", SIZE)
    page = playcanvas_page(chromium)
    for k, c2w in enumerate(poses):  # in front, and from behind
        png = tmp_path / f"playcanvas_sh_{ext[1:]}_{k}.png"
        got = playcanvas_vs_nerfkit(page, tmp_path / f"sh{ext}", c2w, cam, png=png, model=True)
        keep(png, SCREENSHOTS)
        flat = float(psnr(got["playcanvas"], degree_zero(g, c2w, cam)))
        print(f"PlayCanvas vs nerfkit, {ext} with SH, view {k}: {got['psnr']:.2f} dB (degree 0: {flat:.2f} dB), "
              f"vs PlayCanvas's rules {got['psnr_model']:.2f} dB")
        assert got["psnr"] >= SH_FLOOR, got["psnr"]
        assert got["psnr"] >= flat + SH_OVER_FLAT, (got["psnr"], flat)
        assert got["psnr_model"] >= SH_MODEL_FLOOR, got["psnr_model"]

