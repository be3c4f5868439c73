"""`nerfkit view RUN`'s scene: the training cameras it draws."""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest

import nerfkit.viewer.run as viewer_run
from nerfkit.cli.main import main
from nerfkit.core.errors import ConfigError
from nerfkit.rays.correction import pose_error, refined_poses
from nerfkit.run.folder import RunFolder
from nerfkit.viewer.run import check_host, scene_view_of_run


def test_a_pose_refined_run_shows_its_cameras_where_refinement_put_them(procedural_run):
    run = procedural_run[0]
    cfg = RunFolder(run).config()
    given = scene_view_of_run(run, cfg).poses
    assert np.allclose(scene_view_of_run(run, cfg, {"other": 0}).poses, given)
    xi = np.random.default_rng(0).normal(0.0, 0.02, (len(given), 6)).astype(np.float32)
    shown = scene_view_of_run(run, cfg, {"cam_pose": xi}).poses
    assert np.allclose(shown, refined_poses(given, xi), atol=1e-5)
    assert np.median(pose_error(shown, given)[0]) > 0.5  # degrees: moved, not drawn at the given poses


@pytest.mark.parametrize("host, says", [("no-such-host.invalid", "not a name or address this machine knows"),
                                        ("192.0.2.1", "not an address of this machine")])  # TEST-NET-1
def test_a_host_it_cannot_listen_on_is_one_line_before_the_server(procedural_run, monkeypatch, capsys, host, says):
    """`view --host` with a name that does not resolve or an address of another machine: one line, exit 1, and
    the server is never started (before, the viewer waited for ever on a socket it could not bind)."""
    def no_server(*args, **kwargs):
        raise AssertionError("the viewer was started")

    monkeypatch.setattr(viewer_run, "Viewer", no_server)
    assert main(["view", str(procedural_run[0]), "--host", host, "--port", "0"]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"nerfkit view: error: --host {host}: {says}"), lines
    assert "use 127.0.0.1" in lines[0]
    if host == "192.0.2.1":  # train --viewer names its own flag, before the data loads
        run = procedural_run[0]
        data = RunFolder(run).scene()["data_dir"]
        argv = ["train", data, "--out", str(run.parent / "viewer_host"), "--viewer", "--viewer-host", host]
        assert main(argv) == 1 and not (run.parent / "viewer_host").exists()
        assert capsys.readouterr().err.startswith(f"nerfkit train: error: --viewer-host {host}: {says}")


def test_hosts_this_machine_listens_on_pass_and_a_silent_resolver_is_given_up_on(monkeypatch):
    for host in ("127.0.0.1", "localhost", "0.0.0.0", ""):  # "": every interface, as http.server reads it
        check_host(host)
    monkeypatch.setattr(socket, "getaddrinfo", lambda *a, **k: time.sleep(30))
    t0 = time.perf_counter()
    monkeypatch.setattr(viewer_run, "RESOLVE_SECONDS", 0.2)
    with pytest.raises(ConfigError, match="no answer from the name resolver in 0.2 s"):
        check_host("slow.example")
    assert time.perf_counter() - t0 < 5
