"""Pose refinement in rounds (--pose-rounds; models/splat/rounds.py): the round and the progress within it, the
state started over at a round's first step with the per-photo corrections kept, and a run through the CLI whose
Gaussians start over at the round's step while its poses go on; the flag refused where it would not be read."""

import json

import numpy as np
import pytest

from nerfkit.cli.main import main
from nerfkit.data.procedural.captures import make_capture
from nerfkit.models.splat.rounds import in_round, round_aux, round_of
from nerfkit.run.folder import RunFolder


def test_round_of_splits_the_progress_into_equal_rounds():
    assert round_of(0.0, 3) == (0, 0.0)
    r, u = round_of(0.5, 3)
    assert r == 1 and u == pytest.approx(0.5)
    r, u = round_of(0.7, 2)
    assert r == 1 and u == pytest.approx(0.4)
    assert round_of(1.0, 3) == (2, 1.0)  # the end of the budget is the last round's end, not a fourth round
    assert round_of(0.99, 1) == (0, pytest.approx(0.99))
    assert round_aux(1) == {} and set(round_aux(2)) == {"round", "round_start"}


class _Adam:
    def init(self, params):
        return {k: ("zeros", np.shape(v)) for k, v in params.items()}


def _init():
    return {"means": np.zeros((4, 3), np.float32), "cam_pose": np.zeros((2, 6), np.float32)}, \
        {"active": np.ones(4, bool), "clock": np.float32(0), **round_aux(2)}


def test_a_rounds_first_step_starts_the_gaussians_over_and_keeps_the_corrections():
    learned = {"means": np.full((4, 3), 7.0, np.float32), "cam_pose": np.full((2, 6), 0.01, np.float32)}
    state = {"params": learned, "opt_state": "moments", "aux": {"active": np.zeros(4, bool),
                                                                 "clock": np.float32(12.5), **round_aux(2)}}
    same, step, u = in_round(state, 40, 0.4, 2, _init, ("cam_pose",), _Adam())
    assert same is state and step == 40 and u == pytest.approx(0.8)  # round 0 goes on
    new, step, u = in_round(state, 50, 0.5, 2, _init, ("cam_pose",), _Adam())
    assert step == 0 and u == 0.0 and int(new["aux"]["round"]) == 1 and int(new["aux"]["round_start"]) == 50
    assert np.all(new["params"]["means"] == 0) and new["aux"]["active"].all()  # started over
    assert np.all(new["params"]["cam_pose"] == 0.01) and float(new["aux"]["clock"]) == 12.5  # kept
    assert new["opt_state"] == {"means": ("zeros", (4, 3)), "cam_pose": ("zeros", (2, 6))}
    later, step, u = in_round(new, 70, 0.7, 2, _init, ("cam_pose",), _Adam())
    assert later is new and step == 20 and u == pytest.approx(0.4)  # counted from the round's first step


@pytest.mark.slow
def test_a_run_in_two_rounds_starts_its_gaussians_over_and_keeps_refining_its_poses(tmp_path, capsys):
    cap = make_capture(tmp_path / "cap", "nerfstudio", n_views=10, size=32, environment=True, pose_noise=(1.0, 0.02),
                       points=3000, seed=3)
    run = tmp_path / "run"
    args = ["train", str(cap), "--out", str(run), "--preset", "splat", "--pose-refine", "on", "--max-steps", "80",
            "--val-every", "80", "--ckpt-every", "80", "--capacity", "4000", "--log-every", "1"]
    assert main([*args, "--pose-rounds", "2", "--pose-solves", "2"]) == 0
    assert "pose refinement in 2 rounds (2 pose solves a round)" in "".join(capsys.readouterr())
    rows = [json.loads(x) for x in (run / "metrics.jsonl").read_text().splitlines()]
    loss = {r["step"]: r["loss"] for r in rows}
    first, late, again = (np.array([loss[s] for s in range(a, a + 5)]) for a in (1, 36, 41))
    print(first, late, again)
    # The second round's first steps train the same views from the same start as the first round's (only the poses
    # differ): their loss is back where the run began, well above where the first round ended.
    assert late.mean() < 0.8 * first.mean() and np.allclose(again, first, rtol=0.1)
    pose = np.asarray(RunFolder(run).load().params["cam_pose"])
    assert np.abs(pose).max() > 1e-4  # the corrections learned in both rounds are the run's
    # refused where it would not be read, and below 1
    for bad, word in ((["--pose-refine", "off", "--pose-rounds", "2"], "--pose-rounds"), (["--pose-rounds", "0"],
                                                                                          "--pose-rounds")):
        assert main([*args, "--overwrite", *bad]) == 1
        err = capsys.readouterr().err
        assert word in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err


def test_the_last_round_holds_the_poses_with_pose_hold_last(tmp_path, capsys):
    """--pose-hold-last on: the rounds before the last refine the poses; the last grows its Gaussians afresh and
    leaves every pose correction where the round before left it (no pose step, no solve)."""
    cap = make_capture(tmp_path / "cap", "nerfstudio", n_views=10, size=32, environment=True, pose_noise=(1.0, 0.02),
                       points=3000, seed=3)
    run = tmp_path / "run"
    args = ["train", str(cap), "--out", str(run), "--preset", "splat", "--pose-refine", "on", "--max-steps", "80",
            "--val-every", "80", "--ckpt-every", "40", "--capacity", "4000", "--pose-rounds", "2", "--pose-solves", "2"]
    assert main([*args, "--pose-hold-last", "on"]) == 0
    assert "pose refinement in 2 rounds, the last holding the poses (2 pose solves a round)" in \
        "".join(capsys.readouterr())
    ckpts = sorted((run / "checkpoints").glob("ckpt_*"))
    assert [int(p.stem.split("_")[-1].split(".")[0]) for p in ckpts] == [40, 80]
    held, end = (np.asarray(RunFolder(run).load(p).params["cam_pose"]) for p in ckpts)
    assert np.abs(held).max() > 1e-4 and np.array_equal(held, end)  # refined in the first round, then held
    assert main([*args, "--overwrite"]) == 0  # without: the last round goes on refining them
    ckpts = sorted((run / "checkpoints").glob("ckpt_*"))
    before, after = (np.asarray(RunFolder(run).load(p).params["cam_pose"]) for p in ckpts)
    assert np.abs(after - before).max() > 1e-5
    capsys.readouterr()
    assert main([*args[:-4], "--overwrite", "--pose-hold-last", "on"]) == 1  # one round: nothing to hold
    err = capsys.readouterr().err
    assert "--pose-hold-last on needs --pose-rounds 2" in err and len(err.strip().splitlines()) == 1, err
