"""Mass and centre of gravity from roll (Linder et al. 2015): model, basin simulation,
the paper's multi-dataset IV / LS estimators and ours (refined IV; joint output error, the
default). See :func:`estimate_from_files`."""

from identify.rollmass.api import estimate_from_files, parse_known_load

__all__ = ["estimate_from_files", "parse_known_load"]
