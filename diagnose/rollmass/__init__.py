"""Mass and centre of gravity from roll (Linder et al. 2015, seed 003): model, basin simulation,
multi-dataset IV / LS estimators and our improved estimator. See :func:`estimate_from_files`."""

from diagnose.rollmass.api import estimate_from_files, parse_known_load

__all__ = ["estimate_from_files", "parse_known_load"]
