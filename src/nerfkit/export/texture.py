"""A UV-textured mesh: xatlas cuts the surface into charts and packs them into one image; each
texel covered by a triangle takes the field's colour at the surface point it stands for.

Texel t of triangle (a, b, c) with barycentric coordinates (l_a, l_b, l_c) (raster.py, in UV
space) stands for the point x = sum_i l_i x_i with normal n = normalise(sum_i l_i n_i); its colour
is the composited colour of surface.py seen along -n. UV (0, 0) is the image's bottom-left corner
(OpenGL, trimesh's convention: glTF's top-left origin is trimesh's to flip on export), so texel row
= (1 - v) S. Texels no triangle covers take the colour of the nearest covered texel, so bilinear
filtering and mipmaps at chart borders do not pull in black.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

from nerfkit.export.files import write_atomic, write_together
from nerfkit.export.raster import rasterize

PADDING = 2  # texels between charts


def atlas(verts: np.ndarray, faces: np.ndarray, size: int):
    """xatlas charts packed into about size x size texels: (vmapping int [V'] (the input vertex of
    each atlas vertex; vertices on seams are split), faces int [F, 3] into the atlas vertices,
    uv float32 [V', 2] in [0, 1], (width, height) of the atlas)."""
    import xatlas

    a = xatlas.Atlas()
    a.add_mesh(np.asarray(verts, np.float32), np.asarray(faces, np.uint32))
    charts = xatlas.ChartOptions()
    charts.max_iterations = 1
    pack = xatlas.PackOptions()
    pack.resolution, pack.padding, pack.bilinear = size, PADDING, True
    a.generate(charts, pack)
    vmapping, idx, uv = a[0]
    return np.asarray(vmapping, np.int64), np.asarray(idx, np.int64), np.asarray(uv, np.float32), (a.width, a.height)


def texel_points(verts: np.ndarray, normals: np.ndarray, faces: np.ndarray, uv: np.ndarray, width: int, height: int):
    """(covered bool [H, W], points [C, 3], normals [C, 3]) of the C covered texels of an atlas:
    verts / normals [V', 3] and uv [V', 2] per atlas vertex, faces [F, 3]."""
    xy = np.stack([uv[:, 0] * width, (1.0 - uv[:, 1]) * height], -1)
    face_id, bary, _ = rasterize(xy, np.ones(len(uv)), faces, height, width)
    covered = face_id >= 0
    tri = faces[face_id[covered]]  # [C, 3]
    lam = bary[covered][..., None]  # [C, 3, 1]
    pts = np.sum(lam * verts[tri], axis=1)
    nrm = np.sum(lam * normals[tri], axis=1)
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
    return covered, pts.astype(np.float32), nrm.astype(np.float32)


def fill_empty(image: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """image [H, W, C] with each uncovered texel set to its nearest covered texel's value."""
    if covered.all() or not covered.any():
        return image
    _, (ii, jj) = ndimage.distance_transform_edt(~covered, return_indices=True)
    return image[ii, jj]


def bake(verts: np.ndarray, normals: np.ndarray, faces: np.ndarray, size: int, colors_of):
    """(uv [V', 2], faces' [F, 3], atlas vertex positions [V', 3], image uint8 [H, W, 3]) of a mesh
    (verts / normals [V, 3], faces [F, 3]); colors_of(points [M, 3], normals [M, 3]) -> rgb [M, 3]."""
    vmap, f2, uv, (w, h) = atlas(verts, faces, size)
    v2, n2 = verts[vmap], normals[vmap]
    covered, pts, nrm = texel_points(v2, n2, f2, uv, w, h)
    image = np.zeros((h, w, 3), np.float32)
    image[covered] = colors_of(pts, nrm)
    image = fill_empty(image, covered)
    return uv, f2, v2, (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)


def textured_files(out: Path) -> list[Path]:
    """The files a textured export writes: out.glb alone (the image inside), or out.obj with
    out.mtl and out.png beside it."""
    out = Path(out)
    return [out] if out.suffix == ".glb" else [out, out.with_suffix(".mtl"), out.with_suffix(".png")]


def write_textured(out: Path, verts: np.ndarray, faces: np.ndarray, uv: np.ndarray, image: np.ndarray) -> list[Path]:
    """Write a textured mesh with trimesh: .glb (binary glTF, texture embedded) or .obj + .mtl + .png.
    Returns the files written."""
    import trimesh
    out = Path(out)
    material = trimesh.visual.material.SimpleMaterial(image=Image.fromarray(image))
    visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    mesh = trimesh.Trimesh(verts, faces, visual=visual, process=False)
    if out.suffix == ".glb":
        write_atomic(out, lambda tmp: mesh.export(tmp, file_type="glb"))
        return [out]
    from trimesh.exchange.obj import export_obj

    text, files = export_obj(mesh, include_texture=True, return_texture=True, mtl_name=out.with_suffix(".mtl").name)
    # trimesh names the image after the material; point the .mtl at out.png instead
    png = out.with_suffix(".png")
    mtl_key = out.with_suffix(".mtl").name
    images = [k for k in files if k != mtl_key]
    mtl = files[mtl_key].decode()
    for k in images:
        mtl = mtl.replace(k, png.name)
    write_together([(png, lambda tmp: Image.fromarray(image).save(tmp, format="PNG")),  # all three or none
                    (out.with_suffix(".mtl"), lambda tmp: Path(tmp).write_text(mtl)),
                    (out, lambda tmp: Path(tmp).write_text(text))])
    return [out, out.with_suffix(".mtl"), png]
