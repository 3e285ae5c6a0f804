"""CPU of each stage of one ``shiptrial detect`` process, without a profiler (stop 49).

    cd RECORDINGS && PYTHONPATH=REPO nice -n 10 python REPO/benchmarks/bench_detect_stages.py \
        detect run.csv --prior prior.json --profile naval-vessel

Prints the CPU (``time.process_time``) of importing numpy, typer, the app (every command's module)
and detect's own modules, then of the command, with the library stages inside it (each wrapped
function's own total). Python's start-up before this script is what ``python -c pass`` takes. The
command's stdout is discarded; its noise cache is the user's unless ``SHIPTRIAL_DETECT_CACHE_DIR``
says otherwise (a first call writes the entry: time a second one). PYTHONPATH names the tree timed
(the installed package otherwise).
"""

from __future__ import annotations

import sys
import time

from benchmarks.stagetimer import print_stages, run_command_quietly, time_stages

t0 = time.process_time()
import numpy  # noqa: E402,F401

t_numpy = time.process_time()
import typer  # noqa: E402,F401

t_typer = time.process_time()
import cli.app  # noqa: E402
import cli.commands  # noqa: E402,F401  (the typer app and its command modules: cli.app itself defers them)

t_app = time.process_time()
import cli.options  # noqa: E402,F401
import identify.detect.verdict  # noqa: E402,F401
import primitives.heap  # noqa: E402,F401
from identify.detect import api, batch, noisecache, nullsim  # noqa: E402

t_detect = time.process_time()
spent: dict[str, float] = {}


def main() -> None:
    stages = [
        (api, "load_prior", "load_prior"),
        (api, "load_runs", "load_runs"),
        (batch, "detect", "detect (library, per recording)"),
        (api, "predict_with_signatures", "  recording's prediction and signatures"),
        (api, "null_records", "  no-change records"),
        (nullsim, "simulate_r", "    their two yaw-row simulations (since stop 56: the noise's share added in the loop)"),
        (noisecache, "load", "    noise read from the cache"),
        (nullsim, "_linear_inputs", "    their inputs (since stop 56: the clean signals' share only)"),
        (api, "calibrate", "  LR-CUSUM calibration"),
        (api, "calibrate_dead_zone", "  dead-zone calibration"),
    ]
    time_stages(stages, spent, time.process_time)  # the process's: numpy's BLAS threads in
    t_end = run_command_quietly(cli.app.main, sys.argv[1:])
    print_stages(
        f"import numpy {t_numpy - t0:.3f}; typer {t_typer - t_numpy:.3f}; cli.app (every command) "
        f"{t_app - t_typer:.3f}; detect's modules {t_detect - t_app:.3f}; the command {t_end - t_detect:.3f}",
        spent,
    )


if __name__ == "__main__":
    main()
