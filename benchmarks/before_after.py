"""A record's picture before and after: the version of a results image at an older commit beside today's, each
under its commit, for a note or a page to show what changed.

    python benchmarks/before_after.py own_photos_buddha.jpg --before 8ec6ee9 [--after HEAD] [--scale 0.5] [--out NAME]

Reads both versions with `git show REV:benchmarks/results/NAME` and writes benchmarks/results/<stem>_before_after.jpg.
"""

from __future__ import annotations

import argparse
import io
import subprocess
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]


def version(rev: str, name: str) -> Image.Image:
    blob = subprocess.run(["git", "show", f"{rev}:benchmarks/results/{name}"], cwd=ROOT, check=True,
                          capture_output=True).stdout
    return Image.open(io.BytesIO(blob)).convert("RGB")


def labelled(im: Image.Image, text: str) -> np.ndarray:
    band = Image.new("RGB", (im.width, 28), "white")
    ImageDraw.Draw(band).text((8, 8), text, fill="black")
    return np.concatenate([np.asarray(band), np.asarray(im)], axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("name", help="a file under benchmarks/results")
    ap.add_argument("--before", required=True, help="the older commit")
    ap.add_argument("--after", default="HEAD")
    ap.add_argument("--out", default=None)
    ap.add_argument("--scale", type=float, default=0.5, help="of each picture's size (records' pictures are large)")
    a = ap.parse_args()
    revs = [subprocess.run(["git", "rev-parse", "--short", r], cwd=ROOT, check=True, capture_output=True,
                           text=True).stdout.strip() for r in (a.before, a.after)]
    pics = [version(r, a.name) for r in revs]
    pics = [p.resize((round(p.width * a.scale), round(p.height * a.scale)), Image.LANCZOS) for p in pics]
    ims = [labelled(p, f"{a.name} at {r}") for p, r in zip(pics, revs)]
    h = max(x.shape[0] for x in ims)
    ims = [np.pad(x, ((0, h - x.shape[0]), (0, 0), (0, 0)), constant_values=255) for x in ims]
    gap = np.full((h, 16, 3), 255, np.uint8)
    out = ROOT / "benchmarks" / "results" / (a.out or f"{Path(a.name).stem}_before_after.jpg")
    Image.fromarray(np.concatenate([ims[0], gap, ims[1]], axis=1)).save(out, quality=88)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
