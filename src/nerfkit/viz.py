"""Pictures: depth colour maps, image files, side-by-side grids, curves and videos."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import imageio.v2 as imageio_v2
import imageio.v3 as iio
import matplotlib
import numpy as np

matplotlib.use("Agg")


def to_uint8(img: np.ndarray) -> np.ndarray:
    return (np.clip(np.nan_to_num(img), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def depth_range(depths, opacities, threshold: float = 0.5) -> tuple[float, float]:
    """Robust (1st, 99th percentile) depth range over pixels with opacity above threshold."""
    d = np.concatenate([np.ravel(x) for x in depths])
    a = np.concatenate([np.ravel(x) for x in opacities])
    fg = d[a > threshold]
    if fg.size == 0:
        return 0.0, 1.0
    lo, hi = np.percentile(fg, [1, 99])
    return float(lo), float(max(hi, lo + 1e-6))


def colorize_depth(depth: np.ndarray, opacity: np.ndarray, lo: float, hi: float, background=(1.0, 1.0, 1.0)) -> np.ndarray:
    """Turbo colour map of depth normalised to [lo, hi] (near = red... far = blue), faded to
    `background` where opacity is low. depth, opacity [H, W] -> [H, W, 3] in [0, 1]."""
    x = np.clip((depth - lo) / (hi - lo), 0.0, 1.0)
    rgb = matplotlib.colormaps["turbo"](1.0 - x)[..., :3]
    a = np.clip(opacity, 0.0, 1.0)[..., None]
    return rgb * a + (1.0 - a) * np.asarray(background)


def background_rgb(name: str) -> tuple[float, float, float]:
    """The RGB triple of a background name ("white" or "black")."""
    return (1.0, 1.0, 1.0) if name == "white" else (0.0, 0.0, 0.0)


def colorize_renders(renders: list[dict], background) -> tuple[list[np.ndarray], tuple[float, float]]:
    """Depth colour maps of several renders on one shared depth range (so the views of a
    set or the frames of a video are comparable), and that range."""
    lo, hi = depth_range([r["depth_normalized"] for r in renders], [r["opacity"] for r in renders])
    images = [colorize_depth(r["depth_normalized"], r["opacity"], lo, hi, background) for r in renders]
    return images, (lo, hi)


def save_png(path: Path, img: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, to_uint8(img) if img.dtype != np.uint8 else img)


def side_by_side(images: list[np.ndarray], gap: int = 4) -> np.ndarray:
    """Concatenate [H, W, 3] images left to right with a white gap."""
    h = images[0].shape[0]
    sep = np.ones((h, gap, 3), np.float32)
    parts = []
    for k, im in enumerate(images):
        if k:
            parts.append(sep)
        parts.append(im.astype(np.float32) if im.dtype != np.uint8 else im.astype(np.float32) / 255)
    return np.concatenate(parts, axis=1)


def write_video(path: Path, frames: list[np.ndarray], fps: int = 24) -> None:
    """H.264 MP4 (yuv420p, plays in browsers) of float or uint8 [H, W, 3] frames."""
    path.parent.mkdir(parents=True, exist_ok=True)
    frames = [to_uint8(f) if f.dtype != np.uint8 else f for f in frames]
    h, w = frames[0].shape[:2]
    h2, w2 = h - h % 2, w - w % 2  # yuv420p needs even sizes
    with warnings.catch_warnings():
        # imageio-ffmpeg forks ffmpeg; JAX warns about fork in a threaded process, but the
        # child execs ffmpeg at once and never touches JAX.
        warnings.filterwarnings("ignore", message="os.fork", category=RuntimeWarning)
        _write_frames(path, frames, fps, h2, w2)


def _write_frames(path, frames, fps, h2, w2):
    with imageio_v2.get_writer(path, fps=fps, codec="libx264", quality=8, macro_block_size=1,
                               pixelformat="yuv420p", ffmpeg_log_level="error") as writer:
        for f in frames:
            writer.append_data(np.ascontiguousarray(f[:h2, :w2]))


def read_jsonl(path: Path) -> list[dict]:
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text().splitlines():
        line = line.strip()
        if line:
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:
                continue  # a line cut short by a crash; the rest is still good
    return rows


def plot_curves(series: dict[str, tuple[list, list]], path: Path, xlabel: str, ylabel: str, title: str,
                logy: bool = False) -> None:
    """One line per named (x, y) series, written atomically as PNG."""
    import matplotlib.pyplot as plt  # here, not at the top: pyplot costs 0.2 s of every command's start-up

    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for name, (x, y) in series.items():
        if len(x):
            ax.plot(x, y, label=name, marker="o" if len(x) < 30 else None, markersize=3)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if logy:
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    if len(series) > 1:
        ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)
