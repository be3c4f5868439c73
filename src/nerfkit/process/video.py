"""Frames from a video: evenly spaced, the blurrier of each pair dropped.

2N candidate frames are taken at evenly spaced times; of each consecutive pair the one
with the lower sharpness (variance of the Laplacian of its grey levels, the usual blur
measure) is dropped, leaving N frames that still cover the whole video evenly.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from nerfkit.core.errors import DataError


def sharpness(rgb: np.ndarray) -> float:
    """Variance of the Laplacian of the grey image (higher = sharper)."""
    from scipy.ndimage import laplace

    gray = rgb[..., :3].astype(np.float32).mean(-1)
    return float(laplace(gray).var())


def _reader(path: Path):
    import imageio.v2 as imageio

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="os.fork", category=RuntimeWarning)
        try:
            reader = imageio.get_reader(str(path), "ffmpeg")
            n = reader.count_frames()
        except Exception as e:  # noqa: BLE001 - ffmpeg reports every problem as a plain error
            raise DataError(f"{path}: cannot decode this video ({type(e).__name__}: {str(e).splitlines()[0][:160]}); "
                            f"re-encode it as an H.264 MP4") from None
    if n < 1:
        reader.close()
        raise DataError(f"{path}: the video has no frames; re-encode it as an H.264 MP4")
    return reader, n


def select_frames(path: Path, n_frames: int, progress: bool = True) -> list[tuple[int, np.ndarray]]:
    """(frame index, RGB uint8 [H, W, 3]) of the N kept frames, in time order."""
    if n_frames < 3:
        raise DataError(f"--frames must be at least 3 (got {n_frames})")
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such video file")
    reader, total = _reader(path)
    try:
        n_cand = min(total, 2 * n_frames)
        wanted = sorted({int(round(x)) for x in np.linspace(0, total - 1, n_cand)})
        frames = []
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="os.fork", category=RuntimeWarning)
            for k in tqdm(wanted, desc="read video", unit="frame", disable=not progress):
                try:
                    frames.append((k, np.asarray(reader.get_data(k))[..., :3]))
                except (IndexError, RuntimeError, OSError) as e:
                    raise DataError(f"{path}: frame {k} cannot be decoded ({type(e).__name__}); re-encode the video "
                                    f"as an H.264 MP4") from None
    finally:
        reader.close()
    if len(frames) < 3:
        raise DataError(f"{path}: only {len(frames)} frames could be read; at least 3 are needed")
    if len(frames) <= n_frames:
        return frames
    kept = []
    for a in range(0, len(frames) - 1, 2):
        pair = frames[a:a + 2]
        kept.append(max(pair, key=lambda f: sharpness(f[1])))
    if len(frames) % 2:
        kept.append(frames[-1])
    return kept[:n_frames]
