"""A splat pose setting refused through the CLI (tests of --pose-lr, --pose-warmup, --pose-cross-fit)."""

from pathlib import Path

from nerfkit.cli.main import main
from nerfkit.data.procedural.captures import make_capture


def assert_refused(tmp_path: Path, capsys, flag: str, cases) -> None:
    """Each of `cases` (train arguments; --pose-refine on added where a case does not set it) is refused by
    `nerfkit train --preset splat` in one line that names `flag`, exit 1, without a run folder."""
    cap = make_capture(tmp_path / "cap", "nerfstudio", n_views=8, size=16)
    for bad in cases:
        refine = [] if "--pose-refine" in bad else ["--pose-refine", "on"]
        assert main(["train", str(cap), "--out", str(tmp_path / "run"), "--preset", "splat", *refine, *bad]) == 1
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and flag in err and "Traceback" not in err, err
        assert not (tmp_path / "run").exists()
