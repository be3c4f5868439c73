"""Gaussians to and from glTF 2.0 with KHR_gaussian_splatting (the Khronos release candidate of 2026; the PlayCanvas
engine 2.21+ draws it), as .glb (binary) or .gltf (JSON, buffer embedded), through pygltflib.

One primitive of mode POINTS (0) whose attributes are one float accessor each, in one buffer (each view 4-byte
aligned, ARRAY_BUFFER):

    POSITION                                       VEC3   mu (min and max given, as glTF requires)
    KHR_gaussian_splatting:ROTATION                VEC4   the unit quaternion, x y z w (glTF's order)
    KHR_gaussian_splatting:SCALE                   VEC3   e^s (linear)
    KHR_gaussian_splatting:OPACITY                 SCALAR sigmoid(opacity)
    KHR_gaussian_splatting:SH_DEGREE_0_COEF_0      VEC3   sh_dc (colour = 0.2820948 c + 0.5)
    KHR_gaussian_splatting:SH_DEGREE_l_COEF_n      VEC3   band l, n = 0 .. 2l (m = -l .. l), l = 1 .. degree:
                                                          sh_rest[l^2 - 1 + n] (3DGS's basis and order)
    COLOR_0                                        VEC4   unsigned bytes: the degree-0 colour in linear light,
                                                          and the opacity (what a viewer without the extension
                                                          draws as points)

and the extension {"kernel": "ellipse", "colorSpace": "srgb_rec709_display"} (the colours are the photos' sRGB
values, as 3DGS trains them) on the primitive, named in extensionsUsed (not required: a reader without it still
draws the points).

Axes: glTF is +Y up; the capture's coordinates (the Inria .ply's, y down, z forward) are turned 180 degrees
about x, (x, y, z) -> (x, -y, -z), rotations and SH coefficients with them (transform.py), as for SPZ.
"""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np

from nerfkit.models.splat.formats import N_REST, RDF_TO_RUB, SplatFormat, base_colour, unit_quats
from nerfkit.models.splat.transform import transform_gaussians

EXT = "KHR_gaussian_splatting"
ARRAY_BUFFER = 34962
FLOAT = 5126
UNSIGNED_BYTE = 5121


def sh_names(degree: int) -> list[str]:
    """The SH attribute names of bands 1..degree, in sh_rest's order (coefficient k = l^2 - 1 + n)."""
    return [f"{EXT}:SH_DEGREE_{band}_COEF_{n}" for band in range(1, degree + 1) for n in range(2 * band + 1)]


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function undone (IEC 61966-2-1), for COLOR_0, which glTF defines in linear light."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def write_gltf(path: str | Path, g: dict, sh_degree: int = 3) -> None:
    """Write Gaussians (capture coordinates) as .glb or .gltf (by the extension) with `sh_degree` bands."""
    import pygltflib as gl

    p = transform_gaussians({k: np.asarray(v) for k, v in g.items()}, RDF_TO_RUB)
    n = len(p["means"])
    q = unit_quats(np.asarray(p["quats"], np.float64))
    alpha = 1.0 / (1.0 + np.exp(-np.asarray(p["opacity"], np.float64)))
    colour = _srgb_to_linear(base_colour(p["sh_dc"]))
    columns = [("POSITION", np.asarray(p["means"], np.float32)),
               (f"{EXT}:ROTATION", q[:, [1, 2, 3, 0]].astype(np.float32)),
               (f"{EXT}:SCALE", np.exp(np.asarray(p["log_scales"], np.float64)).astype(np.float32)),
               (f"{EXT}:OPACITY", alpha.astype(np.float32)),
               (f"{EXT}:SH_DEGREE_0_COEF_0", p["sh_dc"].reshape(n, 3).astype(np.float32))]
    columns += [(name, p["sh_rest"][:, k].astype(np.float32)) for k, name in enumerate(sh_names(sh_degree))]
    columns.append(("COLOR_0", np.round(255 * np.concatenate([colour, alpha[:, None]], axis=1)).astype(np.uint8)))
    blob, views, accessors, attributes = bytearray(), [], [], gl.Attributes()
    for i, (name, arr) in enumerate(columns):
        raw = np.ascontiguousarray(arr).tobytes()
        views.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(raw), target=ARRAY_BUFFER))
        blob += raw + b"\0" * (-len(raw) % 4)
        kind = {1: gl.SCALAR, 3: gl.VEC3, 4: gl.VEC4}[1 if arr.ndim == 1 else arr.shape[1]]
        acc = gl.Accessor(bufferView=i, componentType=UNSIGNED_BYTE if arr.dtype == np.uint8 else FLOAT, count=n,
                          type=kind, normalized=True if arr.dtype == np.uint8 else None)
        if name == "POSITION":
            acc.min, acc.max = arr.min(axis=0).tolist(), arr.max(axis=0).tolist()
        accessors.append(acc)
        setattr(attributes, name, i)
    primitive = gl.Primitive(attributes=attributes, mode=gl.POINTS,
                             extensions={EXT: {"kernel": "ellipse", "colorSpace": "srgb_rec709_display"}})
    doc = gl.GLTF2(asset=gl.Asset(version="2.0", generator="nerfkit"), scene=0, scenes=[gl.Scene(nodes=[0])],
                   nodes=[gl.Node(mesh=0)], meshes=[gl.Mesh(primitives=[primitive])], accessors=accessors,
                   bufferViews=views, buffers=[gl.Buffer(byteLength=len(blob))], extensionsUsed=[EXT])
    path = Path(path)
    if path.suffix.lower() == ".glb":
        doc.set_binary_blob(bytes(blob))
        doc.save_binary(str(path))
    else:
        doc.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
        doc.save_json(str(path))


def read_gltf(path: str | Path) -> tuple[dict, int]:
    """(Gaussians in the capture's coordinates, SH degree) of the first KHR_gaussian_splatting primitive of a
    .glb or .gltf file (float accessors; the buffer in the .glb or embedded)."""
    import pygltflib as gl

    doc = gl.GLTF2().load(str(path))
    prims = [pr for m in doc.meshes for pr in m.primitives if EXT in (pr.extensions or {})]
    if not prims:
        raise ValueError(f"no primitive with the {EXT} extension")
    attrs = vars(prims[0].attributes)

    def column(name: str, width: int) -> np.ndarray:
        if attrs.get(name) is None:
            raise ValueError(f"no {name} attribute")
        acc = doc.accessors[attrs[name]]
        view = doc.bufferViews[acc.bufferView]
        if acc.componentType != FLOAT or view.byteStride not in (None, 4 * width):
            raise ValueError(f"{name}: only tightly packed float accessors are read")
        data = doc.get_data_from_buffer_uri(doc.buffers[view.buffer].uri) if doc.buffers[view.buffer].uri \
            else doc.binary_blob()
        start = (view.byteOffset or 0) + (acc.byteOffset or 0)
        if start + 4 * width * acc.count > len(data):
            raise ValueError(f"{name}: its accessor runs past the end of the buffer (truncated?)")
        return np.frombuffer(data, "<f4", width * acc.count, start).reshape(acc.count, width)

    q = column(f"{EXT}:ROTATION", 4)
    n = len(q)
    degree = max([d for d in (1, 2, 3) if all(k in attrs and attrs[k] is not None for k in sh_names(d))],
                 default=0)
    rest = np.zeros((n, N_REST, 3), np.float32)
    for k, name in enumerate(sh_names(degree)):
        rest[:, k] = column(name, 3)
    alpha = np.clip(column(f"{EXT}:OPACITY", 1)[:, 0].astype(np.float64), 1e-7, 1 - 1e-7)
    p = {"means": column("POSITION", 3).astype(np.float32), "quats": q[:, [3, 0, 1, 2]].astype(np.float32),
         "log_scales": np.log(np.maximum(column(f"{EXT}:SCALE", 3), 1e-30)).astype(np.float32),
         "opacity": (np.log(alpha) - np.log1p(-alpha)).astype(np.float32),
         "sh_dc": column(f"{EXT}:SH_DEGREE_0_COEF_0", 3).reshape(n, 1, 3).astype(np.float32), "sh_rest": rest}
    return transform_gaussians(p, RDF_TO_RUB), degree


FORMAT = SplatFormat(name="glTF 2.0 with KHR_gaussian_splatting",
                     opens="the PlayCanvas engine; other glTF viewers draw its points",
                     max_sh=3, write=write_gltf, read=read_gltf)
