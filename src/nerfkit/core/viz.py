"""Pictures: depth colour maps, image files, side-by-side grids, curves and videos."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import imageio.v2 as imageio_v2
import imageio.v3 as iio
import matplotlib
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from nerfkit.core.outputs import replace_with

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


LABEL_PX = 13  # height of the label strip above each image of a labelled row
MIN_PANEL_PX = 112  # narrower images are enlarged (nearest neighbour) in comparison pictures, so labels fit


def _text_image(width: int, height: int, lines: list[tuple[int, str]], background=255) -> np.ndarray:
    """A [height, width, 3] float image with text drawn at the given rows (Pillow's built-in font)."""
    im = Image.new("RGB", (max(width, 1), max(height, 1)), (background,) * 3)
    draw = ImageDraw.Draw(im)
    font = ImageFont.load_default()
    ink = 0 if background > 127 else 255
    for y, text in lines:
        draw.text((2, y), text, fill=(ink,) * 3, font=font)
    return np.asarray(im, np.float32) / 255.0


def depth_bar(height: int, lo: float, hi: float, units: str = "", background=(1.0, 1.0, 1.0)) -> np.ndarray:
    """A depth scale for colorize_depth's map: a vertical turbo bar (near at the top, red; far at the bottom,
    blue) with the near and far values beside it. [height, 56, 3] in [0, 1]."""
    bar_w, text_w = 8, 48
    x = np.linspace(0.0, 1.0, height)[:, None]
    bar = np.repeat(matplotlib.colormaps["turbo"](1.0 - x)[..., :3], bar_w, axis=1).astype(np.float32)
    bg = int(round(255 * float(np.mean(background))))
    text = _text_image(text_w, height, [(0, f"{lo:.3g}"), (max(height - 11, 11), f"{hi:.3g}")] +
                       ([(max(height // 2 - 5, 11), units)] if units and height >= 40 else []), bg)
    return np.concatenate([bar, text], axis=1)


def labelled_row(images: list[np.ndarray], labels: list[str], gap: int = 4, background=(1.0, 1.0, 1.0)) -> np.ndarray:
    """Images [H, W_k, 3] side by side (side_by_side), each under a strip with its label."""
    row = side_by_side(images, gap)
    bg = int(round(255 * float(np.mean(background))))
    strip = _text_image(row.shape[1], LABEL_PX, [], bg)
    x = 0
    for im, label in zip(images, labels):
        w = im.shape[1]
        strip[:, x:x + w] = _text_image(w, LABEL_PX, [(0, label)], bg)
        x += w + gap
    return np.concatenate([strip, row], axis=0)


def comparison(gt: np.ndarray, render: np.ndarray, depth_img: np.ndarray, lo: float, hi: float,
               psnr: float | None = None, units: str = "depth", background=(1.0, 1.0, 1.0)) -> np.ndarray:
    """ground truth | render (with its PSNR) | depth and its scale bar, labelled: the picture of one view that
    validation and evaluation write."""
    k = -(-MIN_PANEL_PX // gt.shape[1]) if gt.shape[1] < MIN_PANEL_PX else 1  # small images: enlarged, pixels kept
    gt, render, depth_img = (np.repeat(np.repeat(np.asarray(x, np.float32), k, 0), k, 1)
                             for x in (gt, render, depth_img))
    bar = depth_bar(depth_img.shape[0], lo, hi, units, background)
    title = "render" if psnr is None else f"render {psnr:.2f} dB"
    return labelled_row([gt, render, np.concatenate([depth_img, bar], axis=1)], ["ground truth", title, "depth"],
                        background=background)


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
                logy: bool = False, min_span: float | None = None) -> None:
    """One line per named (x, y) series, written atomically as PNG. Series of few points get markers (and
    their values, when there are at most 5); min_span: the y axis spans at least this much (a PSNR curve that
    moved 0.06 dB is drawn on a 1 dB axis, not as a cliff)."""
    import matplotlib.pyplot as plt  # here, not at the top: pyplot costs 0.2 s of every command's start-up

    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    ys = []
    for name, (x, y) in series.items():
        if len(x):
            ax.plot(x, y, label=name, marker="o" if len(x) < 30 else None, markersize=3 if len(x) > 5 else 5)
            ys += list(y)
            if len(x) <= 5 and not logy:
                for xi, yi in zip(x, y):
                    ax.annotate(f"{yi:.2f}", (xi, yi), textcoords="offset points", xytext=(0, 6), ha="center",
                                fontsize=8)
    finite = [v for v in ys if np.isfinite(v)]
    if min_span and finite and not logy and max(finite) - min(finite) < min_span:
        mid = 0.5 * (max(finite) + min(finite))
        ax.set_ylim(mid - 0.5 * min_span, mid + 0.5 * min_span)
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
    try:
        replace_with(path, lambda tmp: fig.savefig(tmp, format=path.suffix.lstrip(".") or None))
    finally:
        plt.close(fig)
