"""Export a trained run's geometry and cameras in standard formats (`nerfkit export ...`).

    mesh.py        the mesh export: tsdf.py (fusion of rendered depth, the default; its CPU kernel in
                   fusion_kernel.py) or levelset.py
    pointcloud.py  rendered depth of chosen views -> coloured, fused, voxel-downsampled points
    cameras.py     the training cameras as nerfstudio's transforms.json
    pictures.py    a PNG of each export for the run report
    files.py       the capture-frame transform, the --out check and atomic writes

Every file is written in the capture's own coordinates: nerfkit trains in a normalised frame
x_n = M [x, 1] (data/normalize.py; M is kept in RUN/scene.json, read through run/folder.py), and exports map back with M^-1.
"""
