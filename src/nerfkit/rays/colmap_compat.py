"""pycolmap, imported the one safe way.

pycolmap 4.2.1's extension exports its own zlib (`deflate*`) symbols. If it is loaded
before Pillow's `_imaging`, Pillow's PNG encoder binds to them and the process aborts
("free(): invalid pointer" in deflateEnd) at the next PNG save, including matplotlib's
and imageio's. Loading Pillow first keeps its own zlib. Every nerfkit module therefore
imports pycolmap from here: `from nerfkit.rays.colmap_compat import pycolmap`.
"""

import PIL.Image  # noqa: F401  (must be loaded before pycolmap, see above)
import pycolmap  # noqa: E402

__all__ = ["pycolmap"]
