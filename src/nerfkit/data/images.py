"""Reading images and masks, and shrinking them, for every capture format.

Images become float32 RGB in [0, 1]. Alpha (a PNG's own, or an object mask) composites
them on the background colour, as Blender's alpha does:

    rgb = a * rgb + (1 - a) * background

Downscaling by an integer factor s averages s x s blocks (area resampling), so a pixel
of the small image covers exactly the s x s pixels it replaces and intrinsics scale by 1/s.
Every problem is a `DataError` naming the file and the fix.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
from PIL import Image

from nerfkit.core.errors import DataError

# Pillow modes read as they are (palette and 1-bit images are expanded), and the 16-bit gray ones.
_COLOR_MODES = ("1", "L", "LA", "P", "PA", "RGB", "RGBA")
_GRAY16_MODES = ("I;16", "I;16B", "I;16L", "I")


def one_line(e: BaseException, limit: int = 200) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def is_file(p: Path) -> bool:
    try:
        return p.is_file()
    except (OSError, ValueError):  # e.g. a name too long for the file system
        return False


def image_size(path: Path) -> tuple[int, int]:
    """(width, height) from the file header, without decoding the pixels."""
    try:
        with Image.open(path) as im:
            return im.size
    except Image.DecompressionBombError as e:
        raise DataError(f"{path}: image too large to load ({one_line(e)}); shrink it") from None
    except Exception as e:  # noqa: BLE001 - Pillow raises many unrelated types on corrupt files
        raise DataError(f"{path}: unreadable or truncated image ({type(e).__name__}: {one_line(e)}); "
                        f"re-export it as PNG") from None


def check_one_size(sizes: list[tuple[Path, tuple[int, int]]], what: str = "images", fix: str = "resize or remove it"
                   ) -> None:
    """DataError naming the first file whose (width, height) differs from most files' (all must share one)."""
    counts = Counter(size for _, size in sizes)
    if len(counts) < 2:
        return
    (w, h), n = counts.most_common(1)[0]
    path, (ow, oh) = next((p, s) for p, s in sizes if s != (w, h))
    raise DataError(f"{path}: {what[:-1]} is {ow}x{oh} but {n} of the {len(sizes)} {what} are {w}x{h}; all {what} "
                    f"must have one size ({fix})")


def read_rgba(path: Path, expect_size: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """RGB [H, W, 3] and alpha [H, W] float64 in [0, 1] of an image file.

    Accepted: 8-bit RGB / RGBA (RGB without alpha is fully opaque), 8- or 16-bit gray
    (with or without alpha), 1-bit and palette images; 16-bit RGB(A) is read at 8 bits.
    Refused with a DataError: other modes (CMYK, float, ...), unreadable or truncated
    files, and (checked from the header, before decoding) a size other than
    `expect_size` = (width, height).
    """
    try:
        with Image.open(path) as im:
            if expect_size is not None and im.size != tuple(expect_size):
                raise DataError(f"{path}: image is {im.size[0]}x{im.size[1]} but its camera is "
                                f"{expect_size[0]}x{expect_size[1]} (the file changed since the capture was read?); "
                                f"all images must have one size")
            mode = im.mode
            if mode not in _COLOR_MODES + _GRAY16_MODES:
                raise DataError(f"{path}: unsupported image mode {mode!r}; "
                                f"save it as an 8-bit RGB/RGBA or 8/16-bit grayscale PNG")
            im.load()
            if im.mode in _GRAY16_MODES:
                gray = np.asarray(im).astype(np.float64)
                if gray.size and (gray.min() < 0 or gray.max() > 65535):
                    raise DataError(f"{path}: {mode} pixel values outside 0..65535; save it as an 8- or 16-bit PNG")
                rgb = np.repeat((gray / 65535.0)[..., None], 3, -1)
                a = np.ones(gray.shape, np.float64)
            else:
                arr = np.asarray(im.convert("RGBA"), dtype=np.float64) / 255.0
                rgb, a = arr[..., :3], arr[..., 3]
    except DataError:
        raise
    except Image.DecompressionBombError as e:
        raise DataError(f"{path}: image too large to load ({one_line(e)}); shrink it") from None
    except MemoryError:
        raise DataError(f"{path}: not enough memory to decode this image; shrink it") from None
    except Exception as e:  # noqa: BLE001 - Pillow raises many unrelated types on corrupt files
        raise DataError(f"{path}: unreadable or truncated image ({type(e).__name__}: {one_line(e)}); "
                        f"re-export it as PNG") from None
    if rgb.ndim != 3 or rgb.shape[0] == 0 or rgb.shape[1] == 0:
        raise DataError(f"{path}: image has no pixels ({rgb.shape}); re-export it as PNG")
    return rgb, a


def read_masked(path: Path, mask: Path | None, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """RGB [H, W, 3] and alpha [H, W] of an image of `size` = (width, height), its alpha times its
    mask's where it has one (read_rgba, load_mask)."""
    rgb, a = read_rgba(path, size)
    if mask is not None:
        a = a * load_mask(mask, size, path)
    return rgb, a



def composite(rgb: np.ndarray, alpha: np.ndarray, background) -> np.ndarray:
    """rgb * a + (1 - a) * background, float32."""
    out = rgb * alpha[..., None] + (1.0 - alpha[..., None]) * np.asarray(background)
    return out.astype(np.float32)


def load_mask(path: Path, size: tuple[int, int], image: Path) -> np.ndarray:
    """An object mask as alpha [H, W] float64 in [0, 1] (white = object; gray levels, e.g. a
    JPEG's, are kept as partial coverage). `size` = (width, height) of its image."""
    try:
        with Image.open(path) as im:
            if im.size != tuple(size):
                raise DataError(f"{path}: mask is {im.size[0]}x{im.size[1]} but its image {image.name} is "
                                f"{size[0]}x{size[1]}; masks must have their image's size")
            arr = np.asarray(im.convert("L"), dtype=np.float64) / 255.0
    except DataError:
        raise
    except Exception as e:  # noqa: BLE001
        raise DataError(f"{path}: unreadable mask ({type(e).__name__}: {one_line(e)}); re-export it as PNG") from None
    return arr


def area_downscale(img: np.ndarray, factor: int) -> np.ndarray:
    """Average non-overlapping factor x factor blocks: [H, W, ...] -> [H/f, W/f, ...].

    A size that is not a multiple of `factor` loses its last rows / columns (H mod f,
    W mod f), which keeps the principal point where it was."""
    if factor == 1:
        return img
    h, w = img.shape[:2]
    hh, ww = h // factor, w // factor
    img = img[: hh * factor, : ww * factor]
    return img.reshape(hh, factor, ww, factor, *img.shape[2:]).mean(axis=(1, 3))


def resolve_downscale(width: int, height: int, downscale: int | None, target_width: int | None, where: str,
                      exact: bool = True, max_side: int | None = None) -> int:
    """The integer factor to shrink images by.

    downscale wins over target_width (which must divide the width). With neither, the
    smallest power of two that brings the longer side to at most `max_side` (1 if None).
    `exact` (the Blender scenes) also requires the factor to divide the image size;
    otherwise the remainder is cropped (see area_downscale)."""
    if downscale is None:
        if target_width is not None:
            if width % target_width:
                raise DataError(f"{where}: image width {width} is not a multiple of --target-width {target_width}; "
                                f"pass --downscale instead")
            downscale = width // target_width
        else:
            downscale = 1
            while max_side is not None and max(width, height) / downscale > max_side:
                downscale *= 2
    if downscale < 1 or (exact and (width % downscale or height % downscale)):
        raise DataError(f"{where}: --downscale {downscale} does not divide the image size {width}x{height}")
    if width // downscale < 1 or height // downscale < 1:
        raise DataError(f"{where}: --downscale {downscale} leaves no pixels of a {width}x{height} image")
    return downscale
