"""Baking a trained field into a format a browser can ray-march (format.py: the specification)."""
