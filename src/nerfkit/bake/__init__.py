"""Baking a trained run into a page a browser renders in real time: a fast field into the baked format
(models/baked/format.py: the specification) ray-marched by WebGL2 shaders, or splats drawn as they are."""
