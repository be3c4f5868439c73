"""Experiments: several runs that differ in one setting, trained under one budget and compared
in one folder (results table, overlaid curves, image grids, HTML report).

    pe_ablation.py   what positional encoding buys (the reference report's question)
    antialias.py     nerf vs mipnerf, ngp vs ngp --antialias on multiscale data (mip-NeRF's protocol)
    common.py        what they share: budgets, overlaid curves, labelled image grids
    benchmark.py     `nerfkit benchmark`: every scene under a folder, one table
    report.py        the HTML page of an experiment
"""

from nerfkit.experiments.antialias import ANTIALIAS_MODELS, antialias_experiment
from nerfkit.experiments.pe_ablation import PE_ABLATION, pe_ablation

__all__ = ["ANTIALIAS_MODELS", "PE_ABLATION", "antialias_experiment", "pe_ablation"]
