"""3D Gaussian Splatting (Kerbl et al. 2023): projection, SH colour and the differentiable tile rasteriser."""
