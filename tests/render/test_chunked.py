"""Rendering several cameras in one call (Renderer.render_cameras, what the mesh and point-cloud exports do with
small views) gives each camera's own render, for the chunked and the wavefront renderer."""

from __future__ import annotations

import numpy as np

from nerfkit.rays.cameras import Camera
from nerfkit.render.chunked import Renderer
from nerfkit.render.images import make_renderer
from nerfkit.render.wavefront import WavefrontRenderer
from nerfkit.run.folder import RunFolder


def test_several_cameras_in_one_call_render_as_each_alone(procedural_run):
    run, _, poses = procedural_run
    r = RunFolder(run).load()
    cam = Camera.pinhole(64, 64, r.scene["focal"]).scaled(0.25, 16, 16)  # three views: less than one chunk
    cams = [cam, cam.scaled(0.5, 8, 8), cam]
    picks = [poses[0], poses[5], poses[11]]
    wavefront = make_renderer(r.model, 256)
    assert isinstance(wavefront, WavefrontRenderer)
    for renderer in (wavefront, Renderer(r.model, 256)):
        together = renderer.render_cameras(r.params, r.aux, picks, cams, median=True)
        alone = [renderer.render_camera(r.params, r.aux, p, c, median=True) for p, c in zip(picks, cams)]
        assert [t["rgb"].shape for t in together] == [(16, 16, 3), (8, 8, 3), (16, 16, 3)]
        for t, a in zip(together, alone):
            assert set(t) == set(a)
            for k in a:
                np.testing.assert_allclose(t[k], a[k], atol=2e-5, rtol=1e-5, err_msg=k)
        assert np.mean(together[0]["opacity"]) > 0.05  # the views see the scene, not empty space
