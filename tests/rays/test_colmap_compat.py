"""pycolmap must be imported after Pillow (see nerfkit/rays/colmap_compat.py): otherwise the first PNG
save aborts the process. Every module goes through nerfkit.rays.colmap_compat."""

import re
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "nerfkit"


def test_png_saves_after_nerfkit_loads_pycolmap():
    code = ("from nerfkit.rays.cameras import Camera\n"
            "Camera(8, 8, 9.0, 9.0, 4.0, 4.0, 'SIMPLE_RADIAL', (9.0, 4.0, 4.0, 0.1)).directions()\n"
            "import sys; assert 'pycolmap' in sys.modules\n"
            "import numpy as np, imageio.v3 as iio, tempfile, os\n"
            "p = os.path.join(tempfile.mkdtemp(), 'x.png')\n"
            "iio.imwrite(p, (np.random.default_rng(0).random((32, 32, 3)) * 255).astype(np.uint8))\n"
            "print('ok')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]


def test_no_module_imports_pycolmap_directly():
    offenders = [p.name for p in SRC.rglob("*.py") if p.name != "colmap_compat.py"
                 and re.search(r"^\s*(import pycolmap|from pycolmap)", p.read_text(), re.M)]
    assert not offenders, offenders
