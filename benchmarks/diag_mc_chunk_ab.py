"""Paired A/B of the inline Monte Carlo's data step in one process (stop 53, issue 30), where whole
2,000 x 2 runs alternated between checkouts vary by +-10 % on a shared 2-core machine:

- the optimized design's chunks of 250 runs (``run_chunk``, CPU of this thread) with the fixed design's
  inputs read once for the batch (``expdesign.mc_data._batch_inputs``, (1, N, m)) against a (B, N, m)
  stack of them (the code before), alternated chunk by chunk, the same results checked;
- with ``--against CHECKOUT``: ``mc_data.run_noise`` of this tree against that checkout's (loaded from
  its file), 250 runs of 1,000 samples of the model ship's disturbances, the same numbers checked.

    OMP_NUM_THREADS=1 python benchmarks/diag_mc_chunk_ab.py [--pairs 12] [--against ../main]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.run import _design_setup  # noqa: E402
from expdesign import mc_data  # noqa: E402
from expdesign.api import run_design  # noqa: E402
from expdesign.montecarlo import MCConfig, prepare, run_chunk  # noqa: E402
from primitives.simulate import Disturbances  # noqa: E402


def _report(label: str, t: dict[str, list[float]], unit: float = 1.0, fmt: str = ".3f") -> None:
    (a, va), (b, vb) = t.items()
    d = np.array(va) - np.array(vb)
    print(
        f"{label}: {a} median {unit * np.median(va):{fmt}}, {b} median {unit * np.median(vb):{fmt}} CPU over {len(d)} pairs; "
        f"paired difference median {unit * np.median(d):+{fmt}}, {a} lower in {int((d < 0).sum())} of {len(d)}"
    )


def chunks(pairs: int) -> None:
    """The optimized design's chunks with shared against stacked inputs, alternated."""
    prof, prims, _ = _design_setup()
    sh = prepare(prof, {"optimized": run_design(prof, prims).weights}, MCConfig(runs=2000, seed=0), prims)
    run_chunk(sh, "optimized", range(20))  # numba loaded, passes compiled
    shared = mc_data._batch_inputs
    variants = {"shared": shared, "stacked": lambda runs, _shared: np.stack(runs)}
    t: dict[str, list[float]] = {k: [] for k in variants}
    for rep in range(pairs):
        ids = range(250 * (rep % 8), 250 * (rep % 8) + 250)
        res = {}
        for name in list(variants)[:: 1 if rep % 2 == 0 else -1]:
            mc_data._batch_inputs = variants[name]
            c = time.thread_time()
            res[name] = run_chunk(sh, "optimized", ids)
            t[name].append(time.thread_time() - c)
        mc_data._batch_inputs = shared
        assert res["shared"].digest() == res["stacked"].digest()
    _report("optimized chunk of 250 runs (s)", t)


def noise(pairs: int, against: Path) -> None:
    """This tree's run_noise against another checkout's, alternated."""
    spec = importlib.util.spec_from_file_location("other_mc_data", against / "expdesign" / "mc_data.py")
    other = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(other)
    from primitives.ship import load_profile

    d = Disturbances.from_profile(load_profile("model-ship"))
    fns = {
        "this": mc_data.run_noise,
        "other": getattr(other, "run_noise", None) or other._noise,
    }  # _noise: its name before stop 62
    t: dict[str, list[float]] = {k: [] for k in fns}
    for rep in range(pairs):
        outs = {}
        for name in list(fns)[:: 1 if rep % 2 == 0 else -1]:
            gens = [mc_data.run_rng(0, i, 1) for i in range(250 * rep, 250 * rep + 250)]
            offsets = [g.normal(0.0, d.current_offset_std, 2) for g in gens]
            c = time.thread_time()
            outs[name] = fns[name](d, gens, 1000, offsets, heading=False)
            t[name].append(time.thread_time() - c)
        assert all(np.array_equal(a, b) for a, b in zip(outs["this"][:3], outs["other"][:3]))
    _report("run_noise of 250 runs x 1,000 samples (ms)", t, 1e3, ".1f")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=12)
    ap.add_argument("--against", type=Path, default=None, help="another checkout: also its mc_data.run_noise against this tree's")
    a = ap.parse_args()
    chunks(a.pairs)
    if a.against is not None:
        noise(2 * a.pairs, a.against)


if __name__ == "__main__":
    main()
