"""Lens characterisation from flat fields (Goossens et al. 2019, Sec. 2.7 and 3.2)."""

from .onset_fit import OnsetFit, solve_vignetting_circle

__all__ = ["OnsetFit", "solve_vignetting_circle"]
