"""Change detection on many recordings as one job (``shiptrial detect`` on several files): the
job's size decides whether numba's load pays (:func:`primitives.jitloop.job`), and the no-change
records' noise, the same for recordings of the same length, is drawn once
(:func:`identify.detect.nullsim.normals`). Each recording's detection is :func:`identify.detect.api.detect`'s,
to the bit."""

from __future__ import annotations

from collections import Counter

from diagnose.recording import Recording
from identify.detect.api import detect
from identify.detect.verdict import Detection
from identify.detect.yawmodel import YawPrior
from primitives import jitloop


def detect_all(
    recs: list[Recording],
    prior: YawPrior,
    false_alarm: float = 0.02,
    min_change: float = 0.05,
    seed: int = 0,
    null_runs: int = 400,
    n_rdot: float | None = None,
    i_z: float | None = None,
) -> list[Detection]:
    """:func:`detect` on each recording, as one job for the compiled loops (:func:`job_work`): a job of
    under 12,500 samples in all (400 no-change records each: up to two 500 s recordings at 10 Hz) runs
    the numpy loops and does not pay numba's load, a larger one loads it at its first recording (:func:`primitives.jitloop.job`; the same numbers to rounding either way). The
    no-change records' noise draws are the same for recordings of the same length: drawn once
    (:func:`identify.detect.nullsim.normals`)."""
    draws: dict = {}
    count = Counter(r.n_samples for r in recs)
    left = count.copy()
    out = []
    with jitloop.job(job_work(recs, null_runs)):
        for r in recs:
            # a length met once is drawn as detect alone draws it: no copy kept, its noise scaled in place
            keep = draws if count[r.n_samples] > 1 else None
            out.append(detect(r, prior, false_alarm, min_change, seed, null_runs, n_rdot, i_z, draws=keep))
            left[r.n_samples] -= 1
            if not left[r.n_samples]:
                draws.clear()  # no later recording of this length: its draws are not held through the others
    return out


def job_work(recs: list[Recording], null_runs: int = 400) -> int:
    """Batch members x steps that :func:`detect` runs through the compiled loops on ``recs``: the
    ``null_runs`` no-change records of each recording (their prediction and CUSUM; the bootstrap
    ships' simulation is a sixth of it), the size :func:`primitives.jitloop.job` weighs."""
    return int(sum(null_runs * r.n_samples for r in recs))
