"""Item 7: fuzzing the Blender loader.

Random and mutated `transforms_train.json` text, JSON structures and PNG bytes (raw byte
edits, and chunk-aware edits with valid CRCs so the decoder itself is exercised) are fed
to nerfkit.data.formats.blender.load_blender. Every case must either load sensible data or raise
nerfkit's own DataError; any other exception fails the test. The number of cases is
bounded and the run is deterministic (derandomize).
"""

from __future__ import annotations

import json
import shutil
import struct
import tempfile
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from reference import load_blender, read_split_poses

from nerfkit.core.errors import DataError
from nerfkit.data.procedural.scene import make_scene

SETTINGS = settings(max_examples=100, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

_BASE: Path | None = None


def base_scene() -> Path:
    """A valid 2-frame 8x8 scene, made once per session."""
    global _BASE
    if _BASE is None:
        _BASE = make_scene(Path(tempfile.mkdtemp(prefix="nerfkit-fuzz-")) / "scene", size=8, n_train=2, n_val=0,
                           n_test=0, seed=5)
    return _BASE


@pytest.fixture(scope="module", autouse=True)
def _cleanup():
    yield
    if _BASE is not None:
        shutil.rmtree(_BASE.parent, ignore_errors=True)


def load_or_clean_error(write) -> None:
    """Copy the base scene, let `write(dir)` break it, load: success or DataError only."""
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(shutil.copytree(base_scene(), Path(tmp) / "scene"))
        write(root)
        for fn in (lambda: load_blender(root, "train"), lambda: load_blender(root, "train", downscale=2)):
            try:
                data = fn()
            except DataError as e:
                msg = str(e)
                assert msg and "\n" not in msg, repr(msg)
                continue
            n = len(data)
            assert n >= 1 and data.images.shape == (n, data.height, data.width, 3)
            assert data.images.dtype == np.float32 and np.isfinite(data.images).all()
            assert data.images.min() >= 0.0 and data.images.max() <= 1.0
            assert data.poses.shape == (n, 4, 4) and np.isfinite(data.poses).all()
            assert np.isfinite(data.focal) and data.focal > 0
        try:
            read_split_poses(root, "train")
        except DataError:
            pass


# --- byte-level mutations ------------------------------------------------------------------

EDIT = st.tuples(st.sampled_from(["flip", "set", "delete", "insert", "truncate", "dup"]), st.integers(0, 2**20),
                 st.integers(0, 255))


def mutate(data: bytes, edits) -> bytes:
    b = bytearray(data)
    for kind, pos, val in edits:
        if not b:
            b = bytearray([val])
            continue
        i = pos % len(b)
        if kind == "flip":
            b[i] ^= 1 << (val % 8)
        elif kind == "set":
            b[i] = val
        elif kind == "delete":
            del b[i:i + 1 + val % 16]
        elif kind == "insert":
            b[i:i] = bytes([val]) * (1 + val % 8)
        elif kind == "truncate":
            del b[i:]
        else:
            b[i:i] = b[i:i + 1 + val % 32]
    return bytes(b)


BYTES_OR_EDITS = st.one_of(st.lists(EDIT, min_size=1, max_size=5), st.binary(max_size=400),
                           st.sampled_from([b"", b"[" * 100_000, b"\xef\xbb\xbf{}", b"\x80\x04K\x01."]))


def _apply(original: bytes, how) -> bytes:
    return bytes(how) if isinstance(how, bytes) else mutate(original, how)


@SETTINGS
@given(how=BYTES_OR_EDITS)
def test_mutated_transforms_json_text(how):
    def write(root):
        p = root / "transforms_train.json"
        p.write_bytes(_apply(p.read_bytes(), how))

    load_or_clean_error(write)


@SETTINGS
@given(how=BYTES_OR_EDITS, frame=st.integers(0, 1))
def test_mutated_png_bytes(how, frame):
    def write(root):
        p = root / "train" / f"r_{frame}.png"
        p.write_bytes(_apply(p.read_bytes(), how))

    load_or_clean_error(write)


# --- structure-aware mutations ---------------------------------------------------------------

NASTY = st.sampled_from([10**400, -(10**400), 1e308, float("nan"), float("-inf"), True, "1", None, [], {}, 0.69, 4,
                         -1, "./train/r_0", "./train/r_1.png", "", "/", "..", "x" * 300, "a\x00b", "./train"])
JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=12) | NASTY,
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for k, v in enumerate(node):
            yield from _paths(v, prefix + (k,))


@SETTINGS
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), st.booleans(), JSON_VALUES), min_size=1, max_size=3))
def test_mutated_transforms_json_structure(edits):
    def write(root):
        p = root / "transforms_train.json"
        meta = json.loads(p.read_text())
        for pick, delete, value in edits:
            paths = list(_paths(meta))
            path = paths[pick % len(paths)]
            if not path:
                meta = value
                continue
            parent = meta
            for k in path[:-1]:
                parent = parent[k]
            if delete:
                del parent[path[-1]]
            else:
                parent[path[-1]] = value
        p.write_text(json.dumps(meta))  # NaN / Infinity included, as Python writes them

    load_or_clean_error(write)


def _chunks(png: bytes) -> list[tuple[bytes, bytes]]:
    out, i = [], 8
    while i + 8 <= len(png):
        n, kind = struct.unpack(">I4s", png[i:i + 8])
        out.append((kind, png[i + 8:i + 8 + n]))
        i += 12 + n
    return out


def _png(chunks) -> bytes:
    body = b"".join(struct.pack(">I", len(d)) + k + d + struct.pack(">I", zlib.crc32(k + d) & 0xFFFFFFFF)
                    for k, d in chunks)
    return b"\x89PNG\r\n\x1a\n" + body


@SETTINGS
@given(frame=st.integers(0, 1), width=st.integers(0, 40) | st.sampled_from([100_000, 2**31 - 1]),
       height=st.integers(0, 40) | st.sampled_from([65_536, 2**31 - 1]),
       depth=st.sampled_from([1, 2, 4, 8, 16, 3, 0, 255]), color=st.sampled_from([0, 2, 3, 4, 6, 1, 7]),
       interlace=st.sampled_from([0, 1, 2]), keep_ihdr=st.booleans(), raw_edits=st.lists(EDIT, max_size=3),
       extra=st.sampled_from([None, b"PLTE", b"tRNS", b"IEND", b"IHDR", b"gAMA", b"iCCP", b"zTXt", b"iTXt"]),
       payload=st.binary(max_size=24) | st.builds(lambda tail: b"key\x00\x00" + tail, st.binary(max_size=24)))
def test_png_chunks_with_valid_crc(frame, width, height, depth, color, interlace, keep_ihdr, raw_edits, extra,
                                   payload):
    """Edit the header fields and the decompressed pixel data, then re-encode with valid CRCs."""

    def write(root):
        p = root / "train" / f"r_{frame}.png"
        chunks = _chunks(p.read_bytes())
        new = []
        for kind, data in chunks:
            if kind == b"IHDR" and not keep_ihdr:
                data = struct.pack(">IIBBBBB", width, height, depth, color, 0, 0, interlace)
            elif kind == b"IDAT" and raw_edits:
                data = zlib.compress(mutate(zlib.decompress(data), raw_edits))
            new.append((kind, data))
            if extra is not None and kind == b"IHDR":
                new.append((extra, payload))
        p.write_bytes(_png(new))

    load_or_clean_error(write)
