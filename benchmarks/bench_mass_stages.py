"""CPU of each stage of one ``shiptrial mass`` process, without a profiler (stop 51).

    cd EXAMPLE && PYTHONPATH=REPO nice -n 10 python REPO/benchmarks/bench_mass_stages.py \
        mass nominal.csv calibration.csv loaded.csv

(``EXAMPLE`` from ``shiptrial mass-sim EXAMPLE --case case1 --seed 3``: the bundled example.) Prints the
CPU (``time.process_time``) of importing numpy, typer, the app (every command's module) and mass's own
modules (scipy.optimize among them), then of the command, with the library stages inside it (each wrapped
function's own total; nested stages count in both). Python's start-up before this script is what
``python -c pass`` takes. The command's stdout is discarded. PYTHONPATH names the tree timed (the
installed package otherwise); the same script times main's tree and a branch's.
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
from identify.rollmass import api, estimate, oe_fit, output_error, roles, sensitivity  # noqa: E402

t_mass = time.process_time()
spent: dict[str, float] = {}


def main() -> None:
    stages = [
        (api, "estimate_from_files", "estimate_from_files (library)"),
        (api, "read_roll_csv", "  reading the three files"),
        (api, "check_recorded_signs", "  sign and scale checks"),
        (roles, "roll_stiffness", "  role check's roll stiffness (its band-pass in)"),
        (estimate, "referenced_heel", "  heel reference"),
        (estimate, "fit_output_error", "  the oe fit"),
        (output_error._Problem, "residual", "    residuals"),
        (output_error._Problem, "jacobian", "    Jacobians"),
        (output_error._Problem, "discrete", "      their model matrices (finite differences)"),
        (output_error, "dataset_jacobian", "      their sensitivity equations"),
        (sensitivity, "_output_sensitivities", "        forced responses and dy (mode filters in)"),
    ]
    # the load's stationarity check and interval, main's names and stop 52's (the fit calls them from oe_fit)
    for name in ("load_basis", "load_decrement", "load_cov", "load_dof", "load_interval"):
        if hasattr(oe_fit, name):
            stages.append((oe_fit, name, f"    {name}"))
    time_stages(stages, spent, time.process_time)
    t_end = run_command_quietly(cli.app.main, sys.argv[1:])
    print_stages(
        f"import numpy {t_numpy - t0:.3f}; typer {t_typer - t_numpy:.3f}; cli.app (every command) "
        f"{t_app - t_typer:.3f}; mass's modules {t_mass - t_app:.3f}; the command {t_end - t_mass:.3f}; "
        f"all {t_end - t0:.3f}",
        spent,
    )


if __name__ == "__main__":
    main()
