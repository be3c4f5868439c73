"""nerfkit: novel view synthesis from photos."""
