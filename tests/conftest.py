"""Test-session set-up: one persistent JAX compilation cache for the session (in a temporary folder, not the
user's ~/.cache), so functions that several tests compile alike compile once; the session's shared runs, made
once for all test processes (pytest-xdist runs the suite in one process per core, at most MAX_WORKERS, each pinned
to its share of the cores: pinning.py)."""

import os
import shutil
import tempfile
from pathlib import Path

import pytest
from chromium import CHROMIUM_NAMES, find_chromium
from nerfkit.cli.hugepages import glibc_version, huge_page_environment, thp_mode
from nerfkit.core.threads import cpu_count
from pinning import pin_worker
from shared_data import require_shared
from xla_flags import suite_flags

suite_flags()  # before any test starts JAX (xla_flags.py)
# Transparent huge pages for malloc's large blocks in the test processes pytest-xdist starts after this (and their
# subprocesses), as the command line gives itself (nerfkit/cli/hugepages.py): the suite's XLA buffers faulted in 4 KiB
# at a time (a subset of four long files on 2 cores: 35.5 M minor page faults -> 1.2 M, 4:42 -> 3:56 wall).
os.environ.update(huge_page_environment(dict(os.environ), glibc_version(), thp_mode()) or {})

pin_worker(os.environ.get("PYTEST_XDIST_WORKER"), os.environ.get("PYTEST_XDIST_WORKER_COUNT"))  # pinning.py


def pytest_configure(config):
    config.addinivalue_line("markers", "needs_shared(path): needs path under ../shared/data (shared_data.py): skips "
                                       "when it is absent, fails there where $NERFKIT_REQUIRE_SHARED is set (CI)")


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    for mark in item.iter_markers("needs_shared"):
        require_shared(mark.args[0])


MAX_WORKERS = 4  # each test process peaks at about 6 GB of memory


def pytest_xdist_auto_num_workers(config):
    """`-n auto` (pyproject.toml's addopts): one test process per core, at most MAX_WORKERS."""
    return max(1, min(cpu_count(), MAX_WORKERS))


# The suite's longest files, longest first (seconds in one process, 2 cores: `pytest -n 0 --durations=200`), run
# before the rest so that the test processes finish together (the longest first of loadfile's queue: a long file
# taken last would leave one core idle at the end). The second one trains the session's procedural run, so that
# the files after it that use the run find it made. A file missing here only runs later.
LONGEST_FIRST = ("models/test_unbounded.py", "bake/test_bake.py", "cli/test_own_photos.py", "export/test_export.py",
                 "models/test_ngp.py", "cli/test_verb_flags.py", "training/test_flags.py",
                 "viewer/test_viewer_browser.py", "training/test_parallel.py", "cli/test_demo.py",
                 "models/test_ngp_proposal.py", "cli/test_first_hour.py", "reliability/test_bad_runs.py",
                 "training/test_trainer.py", "export/test_glb_browser.py", "experiments/test_antialias.py",
                 "models/splat/test_splat_lens.py", "data/formats/test_multiscale.py")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    tests = Path(__file__).parent

    def key(item):
        try:
            return rank.get(item.path.relative_to(tests).as_posix(), len(rank))
        except ValueError:
            return len(rank)

    items.sort(key=key)  # stable: a file's tests keep their order


def made_once(tmp_path_factory, name: str, make) -> Path:
    """A folder filled by make(folder) once per test session. Under pytest-xdist the first test process to ask
    makes it in a folder all of them share (the others wait on a file lock) and each process gets its own copy,
    so that a test may write into it (exports, eval records) without racing another process."""
    base = tmp_path_factory.getbasetemp()
    try:
        import fcntl
    except ImportError:  # no POSIX file locks (Windows): each process makes its own
        fcntl = None
    if not os.environ.get("PYTEST_XDIST_WORKER") or fcntl is None:
        root = tmp_path_factory.mktemp(name)
        make(root)
        return root

    shared = base.parent / f"shared-{name}"
    shared.mkdir(exist_ok=True)
    with open(base.parent / f"shared-{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not (shared / ".done").exists():
                make(shared)
                (shared / ".done").touch()
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    own = tmp_path_factory.mktemp(name)
    shutil.copytree(shared, own, dirs_exist_ok=True, symlinks=True)
    return own


@pytest.fixture(scope="session", autouse=True)
def compile_cache(tmp_path_factory):
    """A persistent JAX compilation cache for the session, in a temporary folder (not the user's ~/.cache) that
    every test process shares under pytest-xdist, so that a function two processes compile alike compiles
    once. (JAX reads an entry a concurrent write left unfinished as a miss: it warns and compiles.)"""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        path = tmp_path_factory.getbasetemp().parent / "jax-cache"
        path.mkdir(exist_ok=True)
        yield from _with_compile_cache(str(path))
    else:
        with tempfile.TemporaryDirectory(prefix="nerfkit-jax-cache-") as path:
            yield from _with_compile_cache(path)


def _with_compile_cache(path: str):
    old = os.environ.get("NERFKIT_COMPILE_CACHE")
    os.environ["NERFKIT_COMPILE_CACHE"] = path
    from nerfkit.cli.main import enable_compile_cache

    enable_compile_cache()
    yield path
    if old is None:
        os.environ.pop("NERFKIT_COMPILE_CACHE", None)
    else:
        os.environ["NERFKIT_COMPILE_CACHE"] = old


@pytest.fixture(scope="session", autouse=True)
def points_cache(tmp_path_factory):
    """Triangulated points (process/triangulate.py) are cached in a temporary folder for the session, not the
    user's ~/.cache."""
    old = os.environ.get("NERFKIT_POINTS_CACHE")
    path = tmp_path_factory.mktemp("points-cache")
    os.environ["NERFKIT_POINTS_CACHE"] = str(path)
    yield path
    if old is None:
        os.environ.pop("NERFKIT_POINTS_CACHE", None)
    else:
        os.environ["NERFKIT_POINTS_CACHE"] = old


SPLAT_TRAIN = ["--preset", "splat", "--no-progress", "--capacity", "2000", "--max-steps", "200", "--val-every", "100",
               "--ckpt-every", "100", "--log-every", "50"]


@pytest.fixture(scope="session")
def splat_run(tmp_path_factory):
    """(procedural scene at 32 px, run folder of 200 steps of --preset splat with 2,000 Gaussians), shared by
    the splat, web-page and viewer tests."""
    from nerfkit.cli.main import main
    from nerfkit.data.procedural.scene import make_scene

    def make(root):
        scene = make_scene(root / "scene", size=32, n_train=8, n_val=2, n_test=2)
        assert main(["train", str(scene), "--out", str(root / "run"), *SPLAT_TRAIN]) == 0

    root = made_once(tmp_path_factory, "splat_run", make)
    return root / "scene", root / "run"


@pytest.fixture(scope="session")
def procedural_run(tmp_path_factory):
    """(run, moved copy, training poses) of the shared procedural-scene run (procedural_run.py)."""
    from procedural_run import shared_run, train_scene

    return shared_run(made_once(tmp_path_factory, "procedural_run", train_scene))


@pytest.fixture
def chromium():
    """The headless Chromium binary for the real-browser tests (skips, saying how to install it, when absent)."""
    binary = find_chromium()
    if binary is None:
        pytest.skip("no Chromium found (looked for " + ", ".join(CHROMIUM_NAMES) + " and $NERFKIT_CHROMIUM); "
                    "install the Debian package: apt-get install chromium (.ci/run does this)")
    return binary
