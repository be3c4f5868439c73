"""Data-parallel training (nerfkit.training.parallel) on two forced CPU devices: the same losses as one device
with the same global batch, and a two-device checkpoint resumes on one device. Runs in a subprocess,
since XLA_FLAGS=--xla_force_host_platform_device_count=2 must be set before JAX starts."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

SCRIPT = textwrap.dedent('''
    import json, sys
    from pathlib import Path
    import jax
    from nerfkit.core.presets import preset
    from nerfkit.data.procedural.scene import make_scene
    from nerfkit.core.errors import ConfigError
    from nerfkit.training.trainer import Trainer
    from nerfkit.core.viz import read_jsonl
    from nerfkit.cli.main import enable_compile_cache

    enable_compile_cache()  # the session's cache (conftest.py): a step compiled alike twice here compiles once
    root = Path(sys.argv[1])
    scene = make_scene(root / "scene", size=16, n_train=4, n_val=1, n_test=1)

    def train(name, kind, devices, steps, resume=False):
        cfg = preset(kind)
        cfg.train.max_steps, cfg.train.log_every, cfg.train.val_every, cfg.train.devices = steps, 1, 1000, devices
        if kind == "ngp":
            cfg.field.hash_log2_size, cfg.sampler.max_samples, cfg.train.batch_rays = 14, 1 << 14, 1024
            cfg.field.hash_levels, cfg.field.hash_max_res, cfg.sampler.march_steps = 4, 64, 128  # quick to compile
        Trainer(scene, root / name, cfg, resume=resume, progress=False).run()
        return [r["loss"] for r in read_jsonl(root / name / "metrics.jsonl")]

    out = {"devices": len(jax.local_devices())}
    out["tiny1"], out["tiny2"] = train("tiny1", "tiny", 1, 30), train("tiny2", "tiny", 2, 30)
    train("resumed", "tiny", 2, 15)
    out["resumed"] = train("resumed", "tiny", 1, 30, resume=True)
    out["ngp1"], out["ngp2"] = train("ngp1", "ngp", 1, 10), train("ngp2", "ngp", 2, 10)
    try:
        train("odd", "tiny", 3, 2)
    except ConfigError as e:
        out["too_many"] = str(e)
    cfg = preset("tiny")
    cfg.train.batch_rays, cfg.train.devices = 255, 2
    try:
        Trainer(scene, root / "odd", cfg, progress=False)
    except ConfigError as e:
        out["odd_batch"] = str(e)
    print("RESULT " + json.dumps(out))
''')


DEVICE_COUNT = "--xla_force_host_platform_device_count"


def _xla_flags(devices: int | None) -> str:
    """$XLA_FLAGS for a subprocess: this process's (the suite's, xla_flags.py: they compile faster) with any forced
    device count replaced by `devices` CPU devices (None: XLA's one)."""
    flags = [f for f in os.environ.get("XLA_FLAGS", "").split() if not f.startswith(DEVICE_COUNT)]
    return " ".join(flags + ([f"{DEVICE_COUNT}={devices}"] if devices else []))


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    root = tmp_path_factory.mktemp("parallel")
    env = dict(os.environ, JAX_PLATFORMS="cpu", XLA_FLAGS=_xla_flags(devices=2))
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(root)], env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    line = next(x for x in proc.stdout.splitlines() if x.startswith("RESULT "))
    return dict(json.loads(line[len("RESULT "):]), root=str(root))


def _close(a, b, rtol):
    assert len(a) == len(b) > 0
    for x, y in zip(a, b):
        assert abs(x - y) <= rtol * abs(x), (x, y)


def test_two_devices_give_the_losses_of_one(result):
    assert result["devices"] == 2
    _close(result["tiny1"], result["tiny2"], 1e-5)  # rays split: float sums in another order
    _close(result["ngp1"], result["ngp2"], 1e-3)  # packed samples split
    assert result["tiny1"][-1] < result["tiny1"][0]  # and the losses do move


def test_a_two_device_checkpoint_resumes_on_one_device(result):
    _close(result["tiny1"], result["resumed"], 1e-5)


def test_device_count_and_batch_are_checked(result):
    assert "--devices 3" in result["too_many"] and "sees 2 device" in result["too_many"]
    assert "--batch-rays 255 does not split over 2 devices" in result["odd_batch"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_two_processes_on_loopback_train_like_two_devices_and_only_process_0_writes(result):
    """Multi-host data parallelism (parallel.init_distributed) with JAX's CPU backend: two `nerfkit train`
    processes of one device each, joined over 127.0.0.1, give the losses of one process with two devices
    (same global batch, each process rendering its half of the rays); one run folder, written once."""
    root = Path(result["root"])
    out = root / "two_processes"
    port = _free_port()
    cmd = [sys.executable, "-m", "nerfkit", "train", str(root / "scene"), "--out", str(out), "--preset", "tiny",
           "--max-steps", "30", "--log-every", "1", "--val-every", "1000", "--no-progress"]
    procs = []
    for pid in range(2):
        env = dict(os.environ, JAX_PLATFORMS="cpu", NERFKIT_COORDINATOR=f"127.0.0.1:{port}",
                   NERFKIT_NUM_PROCESSES="2", NERFKIT_PROCESS_ID=str(pid))
        env["XLA_FLAGS"] = _xla_flags(devices=None)
        procs.append(subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True))
    logs = [p.communicate(timeout=600)[0] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], "\n".join(x[-2000:] for x in logs)
    assert "run folder" in logs[0] and "run folder" in logs[1]
    rows = [json.loads(x) for x in (out / "metrics.jsonl").read_text().splitlines()]
    assert [r["step"] for r in rows] == list(range(1, 31))  # written once, by process 0
    _close(result["tiny2"], [r["loss"] for r in rows], 1e-5)
    assert (out / "checkpoints" / "ckpt_00000030.msgpack").is_file()


def test_a_bad_multi_process_environment_is_one_clear_line(tmp_path):
    env = dict(os.environ, NERFKIT_COORDINATOR="127.0.0.1:1", NERFKIT_NUM_PROCESSES="2", NERFKIT_PROCESS_ID="5")
    proc = subprocess.run([sys.executable, "-m", "nerfkit", "train", str(tmp_path), "--out", str(tmp_path / "r")],
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert "NERFKIT_PROCESS_ID=5 must be in 0..NERFKIT_NUM_PROCESSES-1 = 1" in proc.stderr
    assert "Traceback" not in proc.stderr
