"""Item 1: bad input is refused before any compute, with a one-line error naming the file
and the fix; what can be read sensibly (grayscale, 16-bit, RGB without alpha, palette,
1-bit) is accepted with the right values.

Complements tests/data/formats/test_blender.py (missing folder / JSON / image, bad JSON, pose
checks, size mismatch, truncated PNG, split ranges, downscale) and tests/cli/test_main.py.
"""

from __future__ import annotations

import io
import json
import shutil
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from reference import load_blender, read_split_poses

from nerfkit.cli.main import main
from nerfkit.core.errors import DataError
from nerfkit.data.procedural.scene import make_scene

SIZE = 8


def png_bytes(arr: np.ndarray, color_type: int, width: int | None = None, height: int | None = None) -> bytes:
    """A minimal PNG encoder (so 16-bit RGB(A) and odd headers can be written exactly).
    color_type: 0 gray, 2 RGB, 4 gray+alpha, 6 RGBA; 16-bit when arr is uint16."""
    depth = 16 if arr.dtype == np.uint16 else 8
    h, w = arr.shape[:2]
    rows = arr.astype(">u2" if depth == 16 else np.uint8).reshape(h, -1).view(np.uint8).reshape(h, -1)
    raw = b"".join(b"\x00" + r.tobytes() for r in rows)

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width or w, height or h, depth, color_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def pil_bytes(im: Image.Image, fmt: str = "PNG", **kw) -> bytes:
    buf = io.BytesIO()
    im.save(buf, fmt, **kw)
    return buf.getvalue()


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("valid") / "scene", size=SIZE, n_train=2, n_val=1, n_test=0, seed=4)


@pytest.fixture
def scene(base, tmp_path):
    return Path(shutil.copytree(base, tmp_path / "scene"))


def _with_image(scene: Path, data: bytes, name: str = "r_1.png") -> Path:
    path = scene / "train" / name
    path.write_bytes(data)
    if name != "r_1.png":
        (scene / "train" / "r_1.png").unlink()
        _edit(scene, lambda m: m["frames"][1].update(file_path=f"./train/{name}"))
    return path


def _edit(scene: Path, fn, split: str = "train"):
    p = scene / f"transforms_{split}.json"
    m = json.loads(p.read_text())
    out = fn(m)
    p.write_text(json.dumps(m if out is None else out))


def _one_line_error(scene: Path, match: str, **kw) -> str:
    with pytest.raises(DataError, match=match) as e:
        load_blender(scene, "train", **kw)
    msg = str(e.value)
    assert "\n" not in msg
    return msg


# --- images: accepted with the right values -------------------------------------------------

GRAY16 = np.full((SIZE, SIZE), 30000, np.uint16)
RGBA16 = np.zeros((SIZE, SIZE, 4), np.uint16)
RGBA16[..., 0], RGBA16[..., 1], RGBA16[..., 2], RGBA16[..., 3] = 40000, 20000, 10000, 65535
RGBA16[:, :4, 3] = 0  # left half transparent


def _la(value, alpha):
    a = np.zeros((SIZE, SIZE, 2), np.uint8)
    a[..., 0], a[..., 1] = value, alpha
    return a


def _palette_with_transparency():
    im = Image.new("P", (SIZE, SIZE), 1)
    im.putpalette([0, 0, 0, 10, 20, 30] + [0] * 762)
    im.paste(0, (0, 0, SIZE // 2, SIZE))
    return pil_bytes(im, transparency=0)


def _one_bit():
    im = Image.new("1", (SIZE, SIZE), 0)
    im.paste(1, (0, 0, SIZE // 2, SIZE))
    return pil_bytes(im)


left = np.arange(SIZE)[None, :, None] < SIZE // 2  # [1, W, 1]: the left half of the image

ACCEPTED = {
    "gray 8-bit": (png_bytes(np.full((SIZE, SIZE), 128, np.uint8), 0), np.full(3, 128 / 255)),
    "gray 16-bit": (png_bytes(GRAY16, 0), np.full(3, 30000 / 65535)),
    "RGB without alpha (opaque)": (png_bytes(np.full((SIZE, SIZE, 3), (200, 100, 50), np.uint8), 2),
                                   np.array([200, 100, 50]) / 255),
    "gray + alpha, opaque": (png_bytes(_la(200, 255), 4), np.full(3, 200 / 255)),
    "gray + alpha, transparent -> background": (png_bytes(_la(200, 0), 4), np.ones(3)),
    # 16-bit RGBA is read at 8 bits (error < 1/255); transparent half shows the white background.
    "RGBA 16-bit": (png_bytes(RGBA16, 6), np.where(left, 1.0, np.array([40000, 20000, 10000]) / 65535)),
    "palette with transparency": (_palette_with_transparency(), np.where(left, 1.0, np.array([10, 20, 30]) / 255)),
    "1-bit": (_one_bit(), np.where(left, 1.0, 0.0)),
}


@pytest.mark.parametrize("name", list(ACCEPTED))
def test_image_kinds_accepted_with_right_values(scene, name):
    data, expected = ACCEPTED[name]
    _with_image(scene, data)
    img = load_blender(scene, "train", background="white").images[1]
    assert img.shape == (SIZE, SIZE, 3) and img.dtype == np.float32
    np.testing.assert_allclose(img, np.broadcast_to(expected, img.shape), atol=1 / 255 + 1e-6)


# --- images: refused, naming the file and the fix --------------------------------------------


@pytest.mark.parametrize("mode,fmt,ext", [("CMYK", "JPEG", "jpg"), ("F", "TIFF", "tif"), ("LAB", "TIFF", "tif")])
def test_unsupported_image_modes_refused(scene, mode, fmt, ext):
    im = Image.new(mode, (SIZE, SIZE))
    if Image.open(io.BytesIO(pil_bytes(im, fmt))).mode != mode:
        pytest.skip(f"this Pillow stores {mode} {fmt} differently")
    _with_image(scene, pil_bytes(im, fmt), name=f"r_1.{ext}")
    msg = _one_line_error(scene, rf"r_1\.{ext}: unsupported image mode '{mode}'")
    assert "PNG" in msg  # says what to convert it to


def test_decompression_bomb_header_is_a_data_error(scene):
    # A header claiming 100000 x 100000 pixels in the first image: Pillow's bomb check, as a DataError.
    (scene / "train" / "r_0.png").write_bytes(png_bytes(np.zeros((1, 1, 4), np.uint8), 6, 100_000, 100_000))
    _one_line_error(scene, r"r_0\.png: image too large")


def test_size_mismatch_is_found_from_the_header(scene):
    # The second image claims 3000 x 3000 pixels but holds data for one: refused from its header as a
    # size mismatch, before decoding (which would have reported a truncated file).
    _with_image(scene, png_bytes(np.zeros((1, 1, 4), np.uint8), 6, 3000, 3000))
    _one_line_error(scene, r"r_1\.png: image is 3000x3000 but \d+ of the \d+ images are 8x8")


def test_the_odd_size_is_blamed_on_the_odd_image_even_when_it_comes_first(tmp_path):
    # r_0 is the one that differs: the message names it, not r_1 (which has the size most images have).
    scene = make_scene(tmp_path / "scene", size=SIZE, n_train=3, n_val=1, n_test=0, seed=4)
    (scene / "train" / "r_0.png").write_bytes(png_bytes(np.zeros((4, 4, 4), np.uint8), 6))
    _one_line_error(scene, r"r_0\.png: image is 4x4 but 2 of the 3 images are 8x8")


@pytest.mark.parametrize("data,match", [
    (b"", "unreadable or truncated"),
    (b"\x89PNG\r\n\x1a\n", "unreadable or truncated"),
    (png_bytes(np.zeros((SIZE, SIZE, 4), np.uint8), 6)[:-30], "unreadable or truncated"),
])
def test_broken_png_bytes(scene, data, match):
    _with_image(scene, data)
    _one_line_error(scene, rf"r_1\.png: {match}")


# --- transforms JSON ------------------------------------------------------------------------


@pytest.mark.parametrize("edit,match", [
    (lambda m: [m], r"transforms_train\.json: expected a JSON object"),
    (lambda m: (m.pop("frames"), None)[1], r"transforms_train\.json: no 'frames' list"),
    (lambda m: (m.pop("camera_angle_x"), None)[1], r"transforms_train\.json: no 'camera_angle_x'"),
    (lambda m: m.update(camera_angle_x="0.7"), r"transforms_train\.json: 'camera_angle_x' must be a number"),
    (lambda m: m.update(camera_angle_x=float("nan")), r"transforms_train\.json: 'camera_angle_x' must be a number"),
    (lambda m: m.update(frames=[]), r"transforms_train\.json: 'train' selects no frames"),
    (lambda m: (m["frames"][0].pop("file_path"), None)[1], r"transforms_train\.json: frame 0 needs 'file_path'"),
    (lambda m: (m["frames"][1].pop("transform_matrix"), None)[1], r"frame 1 needs 'file_path' \(string\) and 'transform_matrix'"),
    (lambda m: m["frames"][1]["transform_matrix"][0].__setitem__(3, 10**400), r"frame 1: transform_matrix is not a 4x4 matrix"),
    (lambda m: m["frames"][1].update(transform_matrix=[["a"] * 4] * 4), r"frame 1: transform_matrix is not a 4x4 matrix"),
    (lambda m: m["frames"][1].update(transform_matrix=None), r"frame 1: transform_matrix must be 4x4"),
    (lambda m: m["frames"][1]["transform_matrix"][0].__setitem__(3, 1e300), r"frame 1: transform_matrix has values "
                                                                           r"beyond 1e12"),
    (lambda m: m["frames"][1]["transform_matrix"][3].__setitem__(0, 0.5), r"frame 1: transform_matrix last row"),
    (lambda m: m["frames"][1].update(file_path="./train/r\x00"), r"frame 1: file_path .* contains a NUL"),
    (lambda m: m["frames"][1].update(file_path="x" * 5000), r"x\.png: missing image for .*frame 1"),
])
def test_bad_transforms_content(scene, edit, match):
    _edit(scene, edit)
    _one_line_error(scene, match)


def test_transforms_json_unreadable_or_odd(scene):
    p = scene / "transforms_train.json"
    text = p.read_bytes()
    p.write_bytes(b"\xff\xfe\x00 garbage")
    _one_line_error(scene, r"transforms_train\.json: not valid JSON")
    p.write_bytes(b"[" * 100_000)  # nested too deeply for the JSON parser
    _one_line_error(scene, r"transforms_train\.json: not valid")
    p.unlink()
    p.mkdir()
    _one_line_error(scene, r"transforms_train\.json: is not a regular file")
    p.rmdir()
    p.write_bytes(b"\xef\xbb\xbf" + text)  # a UTF-8 byte-order mark is accepted
    assert len(load_blender(scene, "train")) == 2


def test_pose_only_reader_checks_ranges_too(scene):
    with pytest.raises(DataError, match=r"transforms_val\.json: index 5 in 'val\[0:5\]' is out of range"):
        read_split_poses(scene, "val[0:5]")
    with pytest.raises(DataError, match=r"selects no frames"):
        read_split_poses(scene, "train[1:1]")
    _edit(scene, lambda m: m.update(camera_angle_x=0.5), split="val")
    with pytest.raises(DataError, match=r"transforms_val\.json: camera_angle_x 0.5 differs"):
        read_split_poses(scene, "train,val")


# --- config values through the CLI ----------------------------------------------------------


@pytest.mark.parametrize("flags,message", [
    (["--max-steps", "-5"], "--max-steps must be >= 0 (got -5)"),
    (["--near", "6", "--far", "2"], "--near must be smaller than --far (got near=6.0, far=2.0)"),
    (["--near", "2", "--far", "2"], "--near must be smaller than --far"),
    (["--n-samples", "0"], "--n-samples must be at least 2 (got 0)"),
    (["--batch-rays", "0"], "--batch-rays must be >= 1 (got 0)"),
    (["--lr", "nan"], "--lr must be a finite number (got nan)"),
    (["--chunk", "0"], "--chunk must be >= 1 (got 0)"),
    (["--downscale", "0"], "--downscale must be a positive integer (got 0)"),
    (["--downscale", "3"], "--downscale 3 does not divide the image size 8x8"),
    (["--train-split", "train[0:9]"], "index 9 in 'train[0:9]' is out of range"),
    (["--preset", "splat"], "--preset given 2 times (tiny, splat); give it once"),
    (["--out", "elsewhere"], "--out given 2 times ("),  # read before tyro parses (--resume), as --preset is
    (["--lr-decay-rate", "inf"], "--lr-decay-rate must be a finite number (got inf)"),
    (["--adam-b2", "1"], "--adam-b2 must be in [0, 1) (got 1.0)"),
    (["--adam-eps", "0"], "--adam-eps must be positive (got 0.0)"),
])
def test_bad_config_values_fail_with_one_line(base, tmp_path, capsys, flags, message):
    rc = main(["train", str(base), "--out", str(tmp_path / "run"), "--preset", "tiny", "--no-progress", *flags])
    err = capsys.readouterr().err.strip()
    assert rc == 1
    assert err.startswith("nerfkit train: error: ") and err.count("\n") == 0 and "Traceback" not in err
    assert message in err
    assert not (tmp_path / "run" / "checkpoints").exists()  # refused before any training


@pytest.mark.parametrize("flags,message", [
    (["--normal-consistency", "0.1", "--normal-consistency-from", "1.5"],
     "--normal-consistency-from must be in [0, 1): the share of the budget before the term comes on (got 1.5)"),
    (["--normal-consistency-from", "0.3"], "--normal-consistency-from has no effect: the surface terms are off; give "
                                           "one a weight (--normal-consistency 0.15)"),
    (["--depth-distortion", "-1"], "--depth-distortion must be >= 0 (got -1.0)"),
    (["--screen-dilation", "inf"], "--screen-dilation must be a finite number (got inf)"),
])
def test_bad_splat_values_fail_with_one_line(base, tmp_path, capsys, flags, message):
    rc = main(["train", str(base), "--out", str(tmp_path / "run"), "--preset", "splat", "--no-progress", *flags])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and err.count("\n") == 0 and "Traceback" not in err and message in err, err
    assert not (tmp_path / "run").exists()


def test_bad_run_config_json_is_a_one_line_error(base, tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", str(base), "--out", str(run), "--preset", "tiny", "--no-progress", "--max-steps", "0",
                 "--train-split", "train", "--val-split", "val"]) == 0
    good = (run / "config.json").read_text()
    for text, match in [("{", "not valid JSON"), (b"\xff\x00", "not valid JSON"),
                        (good.replace('"max_steps": 0', '"max_steps": "abc"'), "train.max_steps must be int"),
                        (good.replace('"kind": "mlp"', '"kind": "bogus"'), "field.kind must be one of"),
                        (good.replace('"near": 2.0', '"near": 9.0'), "--near must be smaller than --far")]:
        (run / "config.json").write_bytes(text if isinstance(text, bytes) else text.encode())
        capsys.readouterr()
        assert main(["eval", str(run), "--data", str(base), "--split", "val"]) == 1
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "config.json" in err and match in err, err


def test_a_run_folder_that_is_a_capture_or_a_file_is_refused(base, tmp_path, capsys):
    """--out naming the capture itself (whose val/ photos --overwrite would remove as a run's val/ renders) or a
    file: one line, exit 1, the capture unchanged."""
    scene = tmp_path / "scene"
    shutil.copytree(base, scene)
    before = sorted(p.relative_to(scene) for p in scene.rglob("*"))
    (tmp_path / "afile").write_text("x")
    for out, says in ((scene, f"--out {scene}: holds a capture (transforms_train.json); write the run to a folder "
                              f"of its own, such as {scene / 'run'}"),
                      (tmp_path / "afile", "is a file; name a folder for the run")):
        rc = main(["train", str(scene), "--out", str(out), "--preset", "tiny", "--no-progress", "--overwrite"])
        err = capsys.readouterr().err.strip()
        assert rc == 1 and err.count("\n") == 0 and says in err, err
    assert sorted(p.relative_to(scene) for p in scene.rglob("*")) == before
    assert main(["train", str(tmp_path / "afile"), "--out", str(tmp_path / "r")]) == 1
    assert "afile: is a file, not a data folder" in capsys.readouterr().err
