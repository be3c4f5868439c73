"""Export a trained run's geometry and cameras in standard formats (`nerfkit export ...`).

    mesh.py        density on a grid -> marching cubes -> coloured, optionally simplified mesh
    pointcloud.py  rendered depth of chosen views -> coloured, fused, voxel-downsampled points
    cameras.py     the training cameras as nerfstudio's transforms.json
    pictures.py    a PNG of each export for the run report
    run.py         the trained run (model, normalisation) and the records written beside the files

Every file is written in the capture's own coordinates: nerfkit trains in a normalised frame
x_n = M [x, 1] (data/normalize.py; M is kept in RUN/scene.json), and exports map back with M^-1.
"""
