"""5,000 fuzz examples of ``shiptrial export`` on a mutated plan.json (issue 29), outside the CI budget.

The property and the strategy are those of ``tests/test_fuzz_loaders.py`` (case ``export``): a
saved plan with an embedded chart, up to three fields dropped, added or replaced by any JSON value
(NUL characters, wrong types, extreme numbers, unknown projections), or raw bytes, exported as
GeoJSON, GPX, RTZ or CSV; the command must exit 0 or 2 with one line ``error:``. Prints the
examples run and the CPU time; the first crashing example (shrunk by hypothesis) fails the run.

    python benchmarks/fuzz_export.py                  # 5,000 examples
    python benchmarks/fuzz_export.py --examples 500 --loader map
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.test_fuzz_loaders import CASES, _check  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=5000)
    ap.add_argument("--loader", default="export", choices=sorted(CASES))
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):  # "wrote ..." / "error: ..."
        _check(a.loader, a.examples)
    print(
        f"{a.loader}: {a.examples} examples, no crash; {time.process_time() - c0:.1f} s CPU, "
        f"{time.perf_counter() - t0:.1f} s wall ({(time.process_time() - c0) / a.examples * 1e3:.1f} ms CPU per example)"
    )


if __name__ == "__main__":
    main()
