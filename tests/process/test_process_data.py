"""`nerfkit process-data`: SfM on real photos (a CI-sized subset of ../shared's maryrose, checked
against its reference poses), video frames, and one-line errors for bad input."""

import math
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from shared_data import SHARED_DATA, needs_shared

from nerfkit.cli.main import main
from nerfkit.data.formats.llff import list_images, read_llff
from nerfkit.data.loader import load_scene, read_capture
from nerfkit.data.procedural.captures import render, ring_poses
from nerfkit.process.align import pose_errors
from nerfkit.process.video import select_frames
from nerfkit.rays.cameras import Camera

MARYROSE = SHARED_DATA / "real" / "maryrose"
needs_maryrose = needs_shared(MARYROSE)
SUBSET = 24  # consecutive photos: every part is seen from nearby angles (strided subsets do not register)


@needs_maryrose
def test_maryrose_subset_registers_and_agrees_with_the_reference_poses(tmp_path, capsys):
    photos = list_images(MARYROSE / "images")[:SUBSET]
    (tmp_path / "images").mkdir()
    (tmp_path / "masks").mkdir()
    for p in photos:
        (tmp_path / "images" / p.name).symlink_to(p)
        (tmp_path / "masks" / f"{p.stem}_mask.JPG").symlink_to(MARYROSE / "masks" / f"{p.stem}_mask.JPG")
    out = tmp_path / "data"
    rc = main(["process-data", "images", str(tmp_path / "images"), "--masks", str(tmp_path / "masks"), "--out",
               str(out), "--max-image-size", "432", "--no-progress"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert f"registered {SUBSET} of {SUBSET} photos (100%)" in printed
    for name in ("transforms.json", "sparse_pc.ply", "cameras.png", "colmap.log", "process.json"):
        assert (out / name).is_file(), name
    assert len(list((out / "images_2").iterdir())) == SUBSET and not (out.parent / ".data.incomplete").exists()
    cap = read_capture(out, "all")
    assert [f.image.name for f in cap.splits["all"]] == [p.name for p in photos]
    assert all(f.mask is not None for f in cap.splits["all"])
    ref = {f.image.name: f.c2w for f in read_llff(MARYROSE, masks=False).splits["all"]}
    pred = np.stack([f.c2w for f in cap.splits["all"]])
    e = pose_errors(pred, np.stack([ref[p.name] for p in photos]))
    # The issue's bounds: 2% of the cameras' radius and 1 degree (measured: ~0.5-0.9% and ~0.3-0.5 deg).
    assert e["centre_max"] < 0.02 and e["rotation_max_deg"] < 1.0, e
    # The focal length agrees with the reference's too (LLFF hwf, scaled to 864 px: 2636.8).
    assert cap.splits["all"][0].camera.fx == pytest.approx(2636.8, rel=0.02)
    # The capture trains through the same loader: masks become the background.
    data = load_scene(out, "test", downscale=4)
    assert data.has_masks and data.images.shape[1:] == (216, 216, 3)


def _write_photos(folder: Path, n: int, size: int = 32) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    paths = []
    for k in range(n):
        p = folder / f"p{k}.png"
        iio.imwrite(p, rng.integers(0, 255, (size, size, 3), dtype=np.uint8))
        paths.append(p)
    return paths


def _bad(argv, capsys, match):
    rc = main(["process-data", *argv, "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 1, err
    assert err.startswith("nerfkit process-data: error: ") and "\n" not in err and "Traceback" not in err
    assert match in err, err
    return err


def test_bad_photo_folders_are_one_line_errors(tmp_path, capsys):
    out = str(tmp_path / "out")
    _bad(["images", str(tmp_path / "nowhere"), "--out", out], capsys, "nowhere: no such folder of photos")
    (tmp_path / "empty").mkdir()
    _bad(["images", str(tmp_path / "empty"), "--out", out], capsys, "0 photos found")
    _write_photos(tmp_path / "two", 2)
    _bad(["images", str(tmp_path / "two"), "--out", out], capsys, "2 photos found (.jpg, .png, .tif, ...); SfM needs "
                                                                   "at least 3")
    photos = _write_photos(tmp_path / "broken", 3)
    photos[1].write_bytes(b"not an image")
    _bad(["images", str(tmp_path / "broken"), "--out", out], capsys, "p1.png: unreadable or truncated image")
    _write_photos(tmp_path / "sizes", 3)
    iio.imwrite(tmp_path / "sizes" / "p2.png", np.zeros((16, 32, 3), np.uint8))
    _bad(["images", str(tmp_path / "sizes"), "--out", out], capsys, "p2.png: photo is 32x16 but 2 of the 3 photos are "
                                                                     "32x32")
    assert not Path(out).exists() and not (tmp_path / ".out.incomplete").exists()  # nothing half-written


def test_bad_masks_are_one_line_errors(tmp_path, capsys):
    _write_photos(tmp_path / "photos", 3)
    (tmp_path / "masks").mkdir()
    iio.imwrite(tmp_path / "masks" / "p0.png", np.full((32, 32), 255, np.uint8))
    iio.imwrite(tmp_path / "masks" / "p1_mask.png", np.full((8, 8), 255, np.uint8))
    base = ["images", str(tmp_path / "photos"), "--out", str(tmp_path / "out"), "--masks", str(tmp_path / "masks")]
    _bad(base, capsys, "p1_mask.png: mask is 8x8 but its image p1.png is 32x32")
    iio.imwrite(tmp_path / "masks" / "p1_mask.png", np.full((32, 32), 255, np.uint8))
    _bad(base, capsys, "no mask for p2.png")
    _bad(base[:4] + ["--masks", str(tmp_path / "nomasks")], capsys, "nomasks: no such folder (--masks)")


def test_sfm_that_registers_too_few_photos_fails_clearly_and_leaves_no_capture(tmp_path, capsys):
    _write_photos(tmp_path / "noise", 4, size=64)  # random noise: nothing matches
    out = tmp_path / "cap"
    err = _bad(["images", str(tmp_path / "noise"), "--out", str(out)], capsys, "too few to train")
    assert "colmap.log" in err and not out.exists()
    assert (tmp_path / ".cap.incomplete" / "colmap.log").is_file()  # kept for the user, clearly incomplete


def test_existing_output_is_not_overwritten(tmp_path, capsys):
    _write_photos(tmp_path / "photos", 3)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep.txt").write_text("mine")
    _bad(["images", str(tmp_path / "photos"), "--out", str(tmp_path / "out")], capsys,
         "out: already exists; choose a new --out or pass --overwrite")
    assert (tmp_path / "out" / "keep.txt").read_text() == "mine"


def _video(path: Path, n: int = 24, size: int = 64, blur_odd: bool = True) -> list[np.ndarray]:
    from scipy.ndimage import uniform_filter

    cam = Camera.pinhole(size, size, 0.5 * size / math.tan(0.35))
    frames = []
    for k, c2w in enumerate(ring_poses(n, seed=0)):
        rgb = np.clip(render(c2w, cam)[0] + 0.3 * (1 - render(c2w, cam)[1])[..., None], 0, 1)
        if blur_odd and k % 2:
            rgb = uniform_filter(rgb, size=(7, 7, 1))
        frames.append((rgb * 255).astype(np.uint8))
    iio.imwrite(path, np.stack(frames), fps=10, codec="libx264", quality=10, macro_block_size=1)
    return frames


def test_video_frames_are_evenly_spread_and_the_blurrier_of_each_pair_is_dropped(tmp_path):
    # 12 frames, every odd one blurred; 6 wanted: the 12 candidates pair up as (0, 1), (2, 3), ...
    _video(tmp_path / "v.mp4", n=12)
    kept = select_frames(tmp_path / "v.mp4", 6, progress=False)
    assert [k for k, _ in kept] == [0, 2, 4, 6, 8, 10]  # the sharp frame of each pair wins
    assert kept[0][1].shape == (64, 64, 3)
    # 24 frames, 4 wanted: 8 evenly spaced candidates over the whole video, one kept per pair.
    _video(tmp_path / "w.mp4", n=24, blur_odd=False)
    idx = [k for k, _ in select_frames(tmp_path / "w.mp4", 4, progress=False)]
    assert len(idx) == 4 and idx == sorted(idx) and idx[0] <= 3 and idx[-1] >= 16


def test_undecodable_video_is_a_one_line_error(tmp_path, capsys):
    (tmp_path / "v.mp4").write_bytes(b"\x00\x00\x00\x18ftypmp42" + b"garbage" * 100)
    _bad(["video", str(tmp_path / "v.mp4"), "--out", str(tmp_path / "o")], capsys, "v.mp4: cannot decode this video")
    _bad(["video", str(tmp_path / "none.mp4"), "--out", str(tmp_path / "o")], capsys, "none.mp4: no such video file")


def test_help_lists_the_options(capsys):
    with pytest.raises(SystemExit) as e:
        main(["process-data", "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for flag in ("--masks", "--camera-model", "--matching", "--frames", "--verbose"):
        assert flag in out
